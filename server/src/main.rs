//! The `landsketch` command line: render views of a scene to image files, or serve them over
//! HTTP and WebSocket.

use anyhow::{Context, Result, bail};
use clap::{Args, Parser, Subcommand};
use landsketch::api::{Server, ServerConfig};
use landsketch::render::{Gpu, Renderer, Style};
use landsketch::scene::Scene;
use landsketch::scene::camera::Camera;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use tracing::info;

#[derive(Parser)]
#[command(name = "landsketch", version, about = "Pen-and-ink renderings of GIS landscapes")]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Render one view of a scene to a PNG file.
    Render(RenderArgs),
    /// Measure temporal coherence: render a smooth camera path (pan, dolly, orbit, roll) from
    /// the scene's default camera and print the motion-compensated flicker of the hybrid
    /// hatching next to plain image-space hatching with the same art map and tone.
    Coherence {
        /// Scene file.
        #[arg(long, env = "LANDSKETCH_SCENE", default_value = "data/boulder/scene.toml")]
        scene: PathBuf,
        /// Frame width in pixels.
        #[arg(long, default_value_t = 512)]
        width: u32,
        /// Frame height in pixels.
        #[arg(long, default_value_t = 384)]
        height: u32,
        /// Frames per path segment (pan, dolly, orbit, roll).
        #[arg(long, default_value_t = 6)]
        steps: usize,
        /// Style overrides applied to both variants (JSON object or file).
        #[arg(long)]
        style: Option<String>,
        /// Print JSON instead of a table.
        #[arg(long)]
        json: bool,
    },
    /// Load a scene and print what it contains (terrain, species, layers, default camera).
    Info {
        /// Scene file.
        #[arg(long, env = "LANDSKETCH_SCENE", default_value = "data/boulder/scene.toml")]
        scene: PathBuf,
    },
    /// Serve rendered views over HTTP and WebSocket (README, "Server").
    Serve(ServerConfig),
}

#[derive(Args)]
struct RenderArgs {
    /// Scene file (data/<scene>/scene.toml).
    #[arg(long, env = "LANDSKETCH_SCENE", default_value = "data/boulder/scene.toml")]
    scene: PathBuf,
    /// Output PNG file.
    #[arg(long, default_value = "view.png")]
    out: PathBuf,
    /// Image width in pixels.
    #[arg(long, default_value_t = 1024)]
    width: u32,
    /// Image height in pixels.
    #[arg(long, default_value_t = 768)]
    height: u32,
    /// Camera position "X,Y" (eye above the terrain) or "X,Y,Z" in scene metres.
    #[arg(long, value_name = "X,Y[,Z]")]
    pos: Option<String>,
    /// Eye height above the terrain in metres when --pos has no Z.
    #[arg(long, default_value_t = 1.7)]
    eye_height: f32,
    /// Compass heading in degrees (0 = north, 90 = east).
    #[arg(long, allow_hyphen_values = true)]
    yaw: Option<f32>,
    /// Degrees above (+) or below (-) the horizon.
    #[arg(long, allow_hyphen_values = true)]
    pitch: Option<f32>,
    /// Vertical field of view in degrees.
    #[arg(long)]
    fov: Option<f32>,
    /// Rotation about the view direction in degrees (positive turns the picture counter-clockwise).
    #[arg(long, allow_hyphen_values = true)]
    roll: Option<f32>,
    /// Style overrides: a JSON object or the path of a JSON file (see README, "Style").
    #[arg(long)]
    style: Option<String>,
}

fn main() -> Result<()> {
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env()
                .unwrap_or_else(|_| "info,wgpu_core=warn,wgpu_hal=warn,naga=warn".into()),
        )
        .with_writer(std::io::stderr)
        .init();
    match Cli::parse().command {
        Command::Render(args) => render(&args),
        Command::Serve(config) => serve(config),
        Command::Coherence { scene, width, height, steps, style, json } => {
            coherence(&scene, width, height, steps, style.as_deref(), json)
        }
        Command::Info { scene } => {
            let scene = load_scene(&scene)?;
            let ([x0, y0], [x1, y1]) = scene.terrain.bounds();
            println!("scene      {}", scene.name);
            println!(
                "terrain    {}x{} cells, x {x0:.0}..{x1:.0} m, y {y0:.0}..{y1:.0} m, {} triangles, CRS {:?}",
                scene.terrain.dem.width,
                scene.terrain.dem.height,
                scene.terrain.mesh.triangle_count(),
                scene.terrain.dem.crs
            );
            for s in &scene.species {
                println!(
                    "species    {:<12} {:>6} triangles, {:.1} m tall",
                    s.name,
                    s.model.triangle_count(),
                    s.model.height()
                );
            }
            for l in &scene.layers {
                println!("layer      {:<12} {:>6} plants", l.name, l.plants.len());
            }
            println!("camera     {:?}", scene.default_camera);
            Ok(())
        }
    }
}

fn load_scene(path: &Path) -> Result<Scene> {
    let started = std::time::Instant::now();
    let scene = Scene::load(path)?;
    info!(scene = %scene.name, plants = scene.plant_count(), ms = started.elapsed().as_millis() as u64, "scene loaded");
    Ok(scene)
}

fn parse_style(arg: Option<&str>) -> Result<Style> {
    let Some(arg) = arg else { return Ok(Style::default()) };
    let text = if arg.trim_start().starts_with('{') {
        arg.to_owned()
    } else {
        std::fs::read_to_string(arg).with_context(|| format!("cannot read style file {arg}"))?
    };
    let style: Style = serde_json::from_str(&text).context("invalid style JSON")?;
    style.validate()?;
    Ok(style)
}

fn camera(args: &RenderArgs, scene: &Scene) -> Result<Camera> {
    let mut camera = scene.default_camera;
    if let Some(pos) = &args.pos {
        let v: Vec<f32> = pos
            .split(',')
            .map(|s| s.trim().parse::<f32>())
            .collect::<Result<_, _>>()
            .with_context(|| format!("--pos {pos:?}: expected X,Y or X,Y,Z numbers"))?;
        camera.position = match v[..] {
            [x, y, z] => [x, y, z],
            [x, y] => {
                let ground = scene
                    .terrain
                    .height_at(f64::from(x), f64::from(y))
                    .with_context(|| format!("--pos {x},{y} is outside the terrain; give X,Y,Z"))?;
                [x, y, ground as f32 + args.eye_height]
            }
            _ => bail!("--pos {pos:?}: expected X,Y or X,Y,Z"),
        };
    }
    camera.yaw = args.yaw.unwrap_or(camera.yaw);
    camera.pitch = args.pitch.unwrap_or(camera.pitch);
    camera.fov = args.fov.unwrap_or(camera.fov);
    camera.roll = args.roll.unwrap_or(camera.roll);
    if !camera.is_valid() {
        bail!("camera out of range: pitch must be within -90..=90, fov within 1..=170 degrees, all values finite");
    }
    Ok(camera)
}

fn coherence(scene: &Path, width: u32, height: u32, steps: usize, style: Option<&str>, json: bool) -> Result<()> {
    use landsketch::render::coherence::{camera_path, flicker};
    use landsketch::render::style::HatchSpace;
    let base = parse_style(style)?;
    let scene = load_scene(scene)?;
    let renderer = Renderer::new(Arc::new(Gpu::new()?), &scene);
    let path = camera_path(&scene.default_camera, steps);
    let mut rows = Vec::new();
    for (name, space) in [("hybrid", HatchSpace::Hybrid), ("image-space", HatchSpace::Image)] {
        let style = Style { hatch_space: space, ..base.clone() };
        rows.push((name, flicker(&renderer, &style, &path, width, height)?));
    }
    if json {
        let map: serde_json::Map<String, serde_json::Value> =
            rows.iter().map(|(name, value)| (name.to_string(), serde_json::json!(value))).collect();
        println!("{}", serde_json::json!({ "frames": path.len(), "width": width, "height": height, "flicker": map }));
    } else {
        println!("{} frames at {width}x{height}: mean motion-compensated luminance difference", path.len());
        for (name, value) in rows {
            println!("{name:<12} {value:.5}");
        }
    }
    Ok(())
}

fn render(args: &RenderArgs) -> Result<()> {
    let style = parse_style(args.style.as_deref())?;
    let scene = load_scene(&args.scene)?;
    let camera = camera(args, &scene)?;
    let gpu = Arc::new(Gpu::new()?);
    let renderer = Renderer::new(gpu, &scene);
    let started = std::time::Instant::now();
    let image = renderer.render(&camera, &style, args.width, args.height)?;
    info!(ms = started.elapsed().as_millis() as u64, triangles = renderer.triangles_per_frame(), "rendered");
    image.save(&args.out).with_context(|| format!("cannot write {}", args.out.display()))?;
    println!("{}", args.out.display());
    Ok(())
}

fn serve(config: ServerConfig) -> Result<()> {
    let runtime = tokio::runtime::Builder::new_multi_thread().enable_all().build()?;
    runtime.block_on(async {
        let server = Server::bind(config).await?;
        server.run(shutdown_signal()).await?;
        Ok(())
    })
}

/// Completes on SIGINT (Ctrl-C) or SIGTERM.
async fn shutdown_signal() {
    let interrupt = async {
        if let Err(error) = tokio::signal::ctrl_c().await {
            tracing::warn!(%error, "cannot listen for Ctrl-C");
            std::future::pending::<()>().await;
        }
    };
    #[cfg(unix)]
    let terminate = async {
        match tokio::signal::unix::signal(tokio::signal::unix::SignalKind::terminate()) {
            Ok(mut signal) => {
                signal.recv().await;
            }
            Err(error) => {
                tracing::warn!(%error, "cannot listen for SIGTERM");
                std::future::pending::<()>().await;
            }
        }
    };
    #[cfg(not(unix))]
    let terminate = std::future::pending::<()>();
    tokio::select! {
        () = interrupt => {}
        () = terminate => {}
    }
}
