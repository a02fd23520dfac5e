//! The `landsketch` command line: render views of a scene to image files, or serve them over
//! HTTP and WebSocket.

use anyhow::{Context, Result, bail};
use clap::{Args, Parser, Subcommand};
use landsketch::api::{Server, ServerConfig};
use landsketch::fields::{self, ColorMapName, ColorMapSpec, FieldKind, Legend, LoadOptions, Lut, Mapping};
use landsketch::gis::{Crs, CrsDefinition, Extent, ReprojectError, Transformer};
use landsketch::prep::cache::DiskCache;
use landsketch::prep::lod::LodSettings;
use landsketch::progress::{Progress, Stage};
use landsketch::render::image_format::ImageFormat;
use landsketch::render::presets::PRESETS;
use landsketch::render::projection::DataView;
use landsketch::render::style::{FrameStyle, LayerStyle, PartialStyle};
use landsketch::render::view_style::{StyleTarget, ViewStyle};
use landsketch::render::{FrameRequest, Gpu, RenderOptions, Renderer, Style};
use landsketch::scene::Scene;
use landsketch::scene::camera::{Camera, Projection};
use landsketch::scene::camera_params::{CameraMode, CameraParams, Source};
use landsketch::scene::config::SceneConfig;
use landsketch::store::Store;
use landsketch::store::request::{DataRequest, LayerCache};
use serde::de::DeserializeOwned;
use std::collections::BTreeMap;
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
    /// Render one view of a scene to a PNG or JPEG file.
    Render(RenderArgs),
    /// Benchmark scenes of several sizes generated from the scene's rules (README, "Benchmark").
    Bench(BenchArgs),
    /// Measure temporal coherence: render a smooth camera path (pan, dolly, orbit, roll) from
    /// the scene's default camera and print the motion-compensated flicker, of the whole frame
    /// and of the terrain alone, of object-space strokes (hybrid plants, terrain strokes on the
    /// ground) next to plain image-space hatching with the same art map and tone.
    Coherence {
        /// Scene file.
        #[arg(long, env = "LANDSKETCH_SCENE", default_value = landsketch::scene::SAMPLE_SCENE)]
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
        /// Write every frame of both variants into this directory (`object-00.png`,
        /// `image-00.png`, …) and each frame's motion-compensated difference to the one before
        /// (`object-difference-01.png`, …: darker where they differ) to see where the figures
        /// come from.
        #[arg(long)]
        frames: Option<PathBuf>,
        #[command(flatten)]
        cache: CacheArgs,
    },
    /// Load a scene and print what it contains (terrain, species, layers, default camera).
    Info {
        /// Scene file.
        #[arg(long, env = "LANDSKETCH_SCENE", default_value = landsketch::scene::SAMPLE_SCENE)]
        scene: PathBuf,
    },
    /// Serve rendered views over HTTP and WebSocket (README, "Server").
    Serve(ServerConfig),
    /// List the style presets with one line each, or the style fields with their ranges.
    Presets {
        /// Print the style schema (every field with its kind, default, range and meaning).
        #[arg(long)]
        schema: bool,
        /// Print JSON instead of text.
        #[arg(long)]
        json: bool,
    },
    /// Write the legend of a data file (GeoTIFF, ASCII grid, NetCDF) under a colour map: a PNG
    /// and its JSON description next to it (same name, `.json`).
    Legend(LegendArgs),
}

#[derive(Args)]
struct LegendArgs {
    /// The data file.
    file: PathBuf,
    /// `scalar` or `label`.
    #[arg(long, default_value = "scalar")]
    kind: String,
    /// Colour map (viridis, magma, rdylbu, tableau10, file, …); default by kind.
    #[arg(long)]
    colormap: Option<String>,
    /// Values at the two ends of the colour map, "LO,HI"; default the data's min and max.
    #[arg(long, allow_hyphen_values = true, value_name = "LO,HI")]
    range: Option<String>,
    /// Opacity 0..1.
    #[arg(long, default_value_t = 1.0)]
    opacity: f32,
    /// Run the colour map backwards.
    #[arg(long)]
    reverse: bool,
    /// The mapping target the legend explains: `color` (the colour map) or `hatch_color` (the
    /// ramp from paper to the ink `--color`).
    #[arg(long, default_value = "color", value_parser = ["color", "hatch_color"])]
    target: String,
    /// Ink of a `hatch_color` legend, sRGB "R,G,B" each 0..1 (default the first slot's,
    /// vermillion).
    #[arg(long, value_name = "R,G,B")]
    color: Option<String>,
    /// Title (default: the file name).
    #[arg(long)]
    title: Option<String>,
    /// Units shown in the title (default: the file's, if any).
    #[arg(long)]
    units: Option<String>,
    /// NetCDF variable.
    #[arg(long)]
    variable: Option<String>,
    /// CRS of a file without one (EPSG:<code> or a PROJ.4 string).
    #[arg(long)]
    crs: Option<String>,
    /// Output PNG; the JSON goes next to it.
    #[arg(long, default_value = "legend.png")]
    out: PathBuf,
}

/// Where preprocessing results (HLPs, baked billboards) are cached between runs.
#[derive(Args)]
struct CacheArgs {
    /// Preprocessing cache directory [default: $XDG_CACHE_HOME/landsketch or ~/.cache/landsketch].
    #[arg(long, env = "LANDSKETCH_CACHE_DIR")]
    cache_dir: Option<PathBuf>,
    /// Keep preprocessing results in memory only.
    #[arg(long)]
    no_cache: bool,
    /// Level-of-detail thresholds in projected plant height (pixels), a JSON object of any of
    /// `full_px`, `hlp_px`, `min_px`, `mass_px`, `grid_px`, `fade`, `hlp_budget`, `billboard_budget`,
    /// `lone_budget`, and `force` (one level for every plant: `full`, `hlp` or `plant`), e.g.
    /// `{"mass_px": 16}`.
    #[arg(long, value_name = "JSON")]
    lod: Option<String>,
}

impl CacheArgs {
    /// Renderer options with this disk cache.
    fn render_options(&self) -> Result<RenderOptions> {
        let lod: LodSettings = match &self.lod {
            Some(json) => serde_json::from_str(json).with_context(|| format!("--lod {json}: invalid JSON"))?,
            None => LodSettings::default(),
        };
        if self.no_cache {
            return Ok(RenderOptions { lod, ..RenderOptions::default() });
        }
        let dir = match &self.cache_dir {
            Some(dir) => dir.clone(),
            None => std::env::var_os("XDG_CACHE_HOME")
                .map(PathBuf::from)
                .or_else(|| std::env::var_os("HOME").map(|home| PathBuf::from(home).join(".cache")))
                .context("no cache directory: set --cache-dir, XDG_CACHE_HOME or HOME, or pass --no-cache")?
                .join("landsketch"),
        };
        let cache = DiskCache::open(&dir).with_context(|| format!("cannot open cache directory {}", dir.display()))?;
        Ok(RenderOptions { cache: Some(Arc::new(cache)), lod, ..RenderOptions::default() })
    }
}

#[derive(Args)]
struct BenchArgs {
    /// Scene file whose placement rules are scaled to each plant count.
    #[arg(long, env = "LANDSKETCH_SCENE", default_value = landsketch::scene::SAMPLE_SCENE)]
    scene: PathBuf,
    /// Plant counts of the generated scenes.
    #[arg(long, value_delimiter = ',', default_value = "100,1000,10000")]
    plants: Vec<usize>,
    /// Presets to measure.
    #[arg(long, value_delimiter = ',', default_value = "photorealism,full_npr")]
    styles: Vec<String>,
    /// Style fields over every preset measured (a JSON object or a file, as `render --style`),
    /// e.g. `{"terrain_stroke_direction": "image"}` to measure a variant.
    #[arg(long, value_name = "JSON|FILE")]
    style: Option<String>,
    /// Frames measured per scene and style.
    #[arg(long, default_value_t = 20)]
    frames: usize,
    /// Frame width in pixels.
    #[arg(long, default_value_t = 1024)]
    width: u32,
    /// Frame height in pixels.
    #[arg(long, default_value_t = 768)]
    height: u32,
    /// The camera's path: `walk` (eye height) or `birds-eye` (300 m up, 35° down).
    #[arg(long, value_enum, default_value = "walk")]
    path: landsketch::bench::BenchPath,
    /// Metres the camera moves per frame.
    #[arg(long, default_value_t = 0.5)]
    step: f32,
    /// Print the report as JSON.
    #[arg(long)]
    json: bool,
    /// With --mappings, every style is measured twice: without and with the data layers.
    #[command(flatten)]
    data: DataArgs,
    #[command(flatten)]
    cache: CacheArgs,
}

#[derive(Args)]
struct RenderArgs {
    /// Scene file (data/<scene>/scene.toml).
    #[arg(long, env = "LANDSKETCH_SCENE", default_value = landsketch::scene::SAMPLE_SCENE)]
    scene: PathBuf,
    /// Output image file: PNG, or JPEG when it ends in `.jpg` or `.jpeg`.
    #[arg(long, default_value = "view.png")]
    out: PathBuf,
    /// Image width in pixels.
    #[arg(long, default_value_t = 1024)]
    width: u32,
    /// Image height in pixels.
    #[arg(long, default_value_t = 768)]
    height: u32,
    /// Camera position "X,Y" (eye above the terrain) or "X,Y,Z" in scene metres.
    #[arg(long, value_name = "X,Y[,Z]", allow_hyphen_values = true)]
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
    /// Style preset to start from (`landsketch presets` lists them).
    #[arg(long)]
    preset: Option<String>,
    /// Style overrides: a JSON object or the path of a JSON file (see README, "Style"); merged
    /// over the preset.
    #[arg(long)]
    style: Option<String>,
    /// A layer's own style, `NAME=JSON` or `NAME=FILE` (NAME `terrain` or a vegetation layer);
    /// the fields merge over the frame's style, or over `"preset"` when the JSON names one.
    /// Repeatable.
    #[arg(long, value_name = "NAME=JSON|FILE")]
    layer_style: Vec<String>,
    /// Plan view instead of perspective: orthographic, top-down, centred on CX,CY and WIDTH
    /// scene metres across; --yaw turns the heading that points up (0 north).
    #[arg(long, value_name = "CX,CY,WIDTH", allow_hyphen_values = true, conflicts_with_all = ["pos", "pitch", "fov"])]
    plan: Option<String>,
    /// A named viewpoint of the scene file (`[[viewpoints]]`): its camera, and its preset and
    /// style under --preset and --style.
    #[arg(long, value_name = "NAME", conflicts_with_all = ["pos", "plan", "yaw", "pitch", "fov", "roll"])]
    viewpoint: Option<String>,
    #[command(flatten)]
    data: DataArgs,
    #[command(flatten)]
    cache: CacheArgs,
}

/// Data layers drawn into the frames of `render` and `bench`.
#[derive(Args)]
struct DataArgs {
    /// Layer store of the data layers named in --mappings (the server's --data-dir).
    #[arg(long, env = "LANDSKETCH_DATA_DIR", default_value = "landsketch-data")]
    data_dir: PathBuf,
    /// Data-layer mappings: a JSON array as in the render API (guide, "Data layers") or a file.
    #[arg(long)]
    mappings: Option<String>,
    /// ISO 8601 time of the data layers.
    #[arg(long)]
    time: Option<String>,
}

fn main() -> std::process::ExitCode {
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env()
                .unwrap_or_else(|_| "info,wgpu_core=warn,wgpu_hal=warn,naga=warn".into()),
        )
        .with_writer(std::io::stderr)
        .init();
    match run(Cli::parse().command) {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(error) => {
            eprintln!("{}", error_report(&error));
            std::process::ExitCode::FAILURE
        }
    }
}

/// The error as the CLI prints it: its message, then each cause that the message before it
/// does not already quote (the library's errors name their cause in their own text), and no
/// stack trace whatever `RUST_BACKTRACE` says: a user reads a message, not a debug dump.
fn error_report(error: &anyhow::Error) -> String {
    let mut report = format!("Error: {error}");
    let mut before = error.to_string();
    for cause in error.chain().skip(1) {
        let text = cause.to_string();
        if !before.contains(&text) {
            report.push_str(&format!("\n  caused by: {text}"));
        }
        before = text;
    }
    report
}

/// Runs one command of the CLI.
fn run(command: Command) -> Result<()> {
    match command {
        Command::Render(args) => render(&args),
        Command::Bench(args) => bench(&args),
        Command::Legend(args) => legend(&args),
        Command::Serve(config) => serve(config),
        Command::Coherence { scene, width, height, steps, style, json, frames, cache } => {
            let output = CoherenceOutput { json, frames };
            coherence(&scene, width, height, steps, style.as_deref(), &output, &cache)
        }
        Command::Presets { schema, json } => {
            presets(schema, json);
            Ok(())
        }
        Command::Info { scene } => {
            let bar = LoadBar::start();
            let scene = load_scene(&scene, &bar)?;
            bar.finish();
            let ([x0, y0], [x1, y1]) = scene.terrain.bounds();
            println!("scene      {}", scene.name);
            println!(
                "terrain    {}x{} cells, x {x0:.0}..{x1:.0} m, y {y0:.0}..{y1:.0} m, {} triangles",
                scene.terrain.dem.width,
                scene.terrain.dem.height,
                scene.terrain.mesh.triangle_count(),
            );
            let drape = &scene.terrain.drape;
            if drape.width > 1 || drape.height > 1 {
                println!("drape      {}x{} cells of {:.1} m", drape.width, drape.height, drape.cell);
            }
            for class in drape.present_classes() {
                let [r, g, b] = class.rgb8();
                println!(
                    "ground     {:>4} {:<24} #{r:02x}{g:02x}{b:02x} tone {:+.2}",
                    class.code, class.name, class.tone
                );
            }
            let crs = scene.terrain.dem.crs;
            let e = scene.terrain.dem.extent();
            println!("crs        {crs}");
            // Degrees to about a centimetre, projected units to the centimetre.
            let digits = if crs.is_geographic() { 7 } else { 2 };
            println!(
                "extent     x {:.digits$} .. {:.digits$}, y {:.digits$} .. {:.digits$} in {crs}",
                e.min_x, e.max_x, e.min_y, e.max_y
            );
            match wgs84_extent(&crs, &e) {
                Ok((lo, hi)) => println!(
                    "wgs84      lon {:.6} .. {:.6}, lat {:.6} .. {:.6} (EPSG:4326)",
                    lo[0], hi[0], lo[1], hi[1]
                ),
                Err(err) => println!("wgs84      not available: {err}"),
            }
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
            let c = &scene.default_camera;
            let [x, y, z] = c.position;
            let view = match c.projection {
                Projection::Perspective => format!("perspective, fov {:.1}°", c.fov),
                Projection::Plan { width } => format!("plan view {width:.0} m across"),
            };
            println!(
                "camera     at x {x:.1}, y {y:.1}, z {z:.1} m, heading {:.1}°, pitch {:.1}°, roll {:.1}°, {view}",
                c.yaw, c.pitch, c.roll
            );
            Ok(())
        }
    }
}

/// The lon/lat box (WGS 84) of an extent in `crs`, from its edges sampled at 16 points each.
fn wgs84_extent(crs: &Crs, e: &Extent) -> Result<([f64; 2], [f64; 2]), ReprojectError> {
    let to_wgs84 = Transformer::new(&CrsDefinition::from_crs(crs)?, &CrsDefinition::wgs84())?;
    let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
    for k in 0..=16 {
        let t = f64::from(k) / 16.0;
        let (x, y) = (e.min_x + t * e.width(), e.min_y + t * e.height());
        for (px, py) in [(x, e.min_y), (x, e.max_y), (e.min_x, y), (e.max_x, y)] {
            if let Some((lon, lat)) = to_wgs84.transform(px, py) {
                lo = [lo[0].min(lon), lo[1].min(lat)];
                hi = [hi[0].max(lon), hi[1].max(lat)];
            }
        }
    }
    if lo[0].is_finite() {
        Ok((lo, hi))
    } else {
        Err(ReprojectError::NoOverlap { what: "no point of the extent".into(), crs: "EPSG:4326 (WGS 84)".into() })
    }
}

/// Loads a scene file, its stages shown on `bar`.
fn load_scene(path: &Path, bar: &LoadBar) -> Result<Scene> {
    let started = std::time::Instant::now();
    let scene = Scene::load_with(path, bar)?;
    info!(scene = %scene.name, plants = scene.plant_count(), ms = started.elapsed().as_millis() as u64, "scene loaded");
    Ok(scene)
}

/// The command line's progress bar while a scene loads and the renderer preprocesses it
/// (`render`, `info`, `coherence`); drawn on stderr only when that is a terminal.
struct LoadBar(indicatif::ProgressBar);

impl LoadBar {
    fn start() -> Arc<LoadBar> {
        let bar = indicatif::ProgressBar::new(100);
        if let Ok(style) = indicatif::ProgressStyle::with_template("{bar:30} {pos:>3} % {msg}") {
            bar.set_style(style);
        }
        Arc::new(LoadBar(bar))
    }

    /// The renderer options of `cache` reporting to this bar.
    fn render_options(self: &Arc<Self>, cache: &CacheArgs) -> Result<RenderOptions> {
        Ok(RenderOptions { progress: Some(self.clone()), ..cache.render_options()? })
    }

    fn finish(&self) {
        self.0.finish_and_clear();
    }
}

impl std::fmt::Debug for LoadBar {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("LoadBar")
    }
}

impl Progress for LoadBar {
    fn report(&self, stage: Stage, fraction: f32) {
        self.0.set_position(stage.percent(fraction).round() as u64);
        self.0.set_message(stage.label());
    }
}

/// A JSON object given inline or as the path of a JSON file: the style fields of `--style`,
/// a layer style of `--layer-style`.
fn json_object<T: DeserializeOwned>(arg: &str) -> Result<T> {
    let text = if arg.trim_start().starts_with('{') {
        arg.to_owned()
    } else {
        std::fs::read_to_string(arg).with_context(|| format!("cannot read style file {arg}"))?
    };
    serde_json::from_str(&text).with_context(|| format!("invalid style (a JSON object of style fields): {arg}"))
}

/// The styles the flags give: `--preset`, the `--style` fields and every `--layer-style
/// NAME=JSON|FILE`.
fn view_style(preset: Option<&str>, style: Option<&str>, layer_styles: &[String]) -> Result<ViewStyle> {
    let mut layers = BTreeMap::new();
    for arg in layer_styles {
        let (name, json) = arg.split_once('=').with_context(|| format!("--layer-style {arg:?}: expected NAME=JSON"))?;
        let layer: LayerStyle = json_object(json).with_context(|| format!("--layer-style {name}"))?;
        layers.insert(name.to_owned(), layer);
    }
    let style: PartialStyle = style.map(json_object).transpose()?.unwrap_or_default();
    Ok(ViewStyle { preset: preset.map(str::to_owned), style, layer_styles: layers })
}

/// The frame's styles of `styles` in `scene` (errors name the flag).
fn frame_style(styles: &ViewStyle, scene: &Scene) -> Result<FrameStyle> {
    styles.resolve(&scene.layer_names()).map_err(|e| match &e.target {
        StyleTarget::View => anyhow::anyhow!("{e}"),
        StyleTarget::Layer(name) => anyhow::anyhow!("--layer-style {name}: {e}"),
    })
}

/// `landsketch presets`: the presets (name and description) or the style schema.
fn presets(schema: bool, json: bool) {
    match (schema, json) {
        (false, false) => {
            for p in PRESETS {
                println!("{:<22} {}", p.name, p.description);
            }
        }
        (false, true) => {
            /// A preset as `--json` prints it.
            #[derive(serde::Serialize)]
            struct PresetJson {
                name: &'static str,
                description: &'static str,
                style: PartialStyle,
            }
            let list: Vec<_> = PRESETS
                .iter()
                .map(|p| PresetJson { name: p.name, description: p.description, style: p.overrides() })
                .collect();
            println!("{}", serde_json::to_string(&list).unwrap_or_default());
        }
        (true, false) => {
            for f in Style::schema() {
                let range = match (f.min, f.max) {
                    (Some(lo), Some(hi)) => format!("{lo}..={hi}"),
                    _ => String::new(),
                };
                println!("{:<26} {:<8} {:<22} {:<10} {}", f.name, f.kind, f.default.to_string(), range, f.doc);
            }
        }
        (true, true) => println!("{}", serde_json::json!(Style::schema())),
    }
}

fn camera(args: &RenderArgs, scene: &Scene) -> Result<Camera> {
    if let Some(plan) = &args.plan {
        let v: Vec<f32> = plan
            .split(',')
            .map(|s| s.trim().parse::<f32>())
            .collect::<Result<_, _>>()
            .with_context(|| format!("--plan {plan:?}: expected CX,CY,WIDTH numbers"))?;
        let [cx, cy, width] = v[..] else { bail!("--plan {plan:?}: expected CX,CY,WIDTH") };
        let params = CameraParams {
            mode: Some(CameraMode::Plan),
            center: Some(vec![cx, cy]),
            width: Some(width),
            yaw: args.yaw,
            roll: args.roll,
            ..CameraParams::default()
        };
        return Ok(params.resolve(&scene.default_camera, scene, Source::CommandLine)?.camera);
    }
    // A perspective view: the flags as camera parameters, resolved and checked as the server
    // resolves a request's.
    let position = match &args.pos {
        None => None,
        Some(pos) => {
            let v: Vec<f32> = pos
                .split(',')
                .map(|s| s.trim().parse::<f32>())
                .collect::<Result<_, _>>()
                .with_context(|| format!("--pos {pos:?}: expected X,Y or X,Y,Z numbers"))?;
            if !(2..=3).contains(&v.len()) {
                bail!("--pos {pos:?}: expected X,Y or X,Y,Z");
            }
            Some(v)
        }
    };
    let on_the_ground = position.as_ref().is_some_and(|v| v.len() == 2);
    let params = CameraParams {
        position,
        eye_height: on_the_ground.then_some(args.eye_height),
        yaw: args.yaw,
        pitch: args.pitch,
        fov: args.fov,
        roll: args.roll,
        ..CameraParams::default()
    };
    Ok(params.resolve(&scene.default_camera, scene, Source::CommandLine)?.camera)
}

/// The camera of the scene file's viewpoint `name`; its preset, style and layer styles go
/// under those of the flags in `styles`.
fn viewpoint_camera(path: &Path, name: &str, scene: &Scene, styles: &mut ViewStyle) -> Result<Camera> {
    let config = SceneConfig::load(path)?;
    let Some(viewpoint) = config.viewpoints.iter().find(|v| v.name == name) else {
        let names: Vec<String> = config.viewpoints.iter().map(|v| format!("{:?}", v.name)).collect();
        bail!(
            "--viewpoint {name:?}: {} has no such viewpoint (it has {})",
            path.display(),
            if names.is_empty() { "none".to_owned() } else { names.join(", ") }
        );
    };
    // The viewpoint's styles as the server shows them, the flags' over them.
    let mut merged = landsketch::api::viewpoints::view_params(viewpoint, None, None).view_style();
    merged.merge(styles);
    *styles = merged;
    let resolved = viewpoint.camera.resolve(&scene.default_camera, scene, Source::Body);
    Ok(resolved.with_context(|| format!("viewpoint {name:?} of {}", path.display()))?.camera)
}

/// What `landsketch coherence` prints and writes besides its figures.
struct CoherenceOutput {
    json: bool,
    frames: Option<PathBuf>,
}

fn coherence(
    scene: &Path,
    width: u32,
    height: u32,
    steps: usize,
    style: Option<&str>,
    output: &CoherenceOutput,
    cache: &CacheArgs,
) -> Result<()> {
    use landsketch::render::coherence::{Flicker, camera_path, measure_path};
    use landsketch::render::style::{HatchSpace, TerrainStrokes};
    let styles = view_style(None, style, &[])?;
    let bar = LoadBar::start();
    let scene = load_scene(scene, &bar)?;
    let base = frame_style(&styles, &scene)?.base;
    let renderer = Renderer::with_options(Arc::new(Gpu::new()?), &scene, &bar.render_options(cache)?)?;
    bar.finish();
    let path = camera_path(&scene.default_camera, steps);
    // The default: hybrid plants on object-space terrain (fall line unless the style names a
    // direction); the baseline: image-space hatching of both.
    let terrain = match base.terrain_stroke_direction {
        TerrainStrokes::Image => TerrainStrokes::FallLine,
        direction => direction,
    };
    let object = Style { hatch_space: HatchSpace::Hybrid, terrain_stroke_direction: terrain, ..base.clone() };
    let image = Style { hatch_space: HatchSpace::Image, terrain_stroke_direction: TerrainStrokes::Image, ..base };
    let object_run = measure_path(&renderer, &object, &path, width, height)?;
    let image_run = measure_path(&renderer, &image, &path, width, height)?;
    if let Some(dir) = &output.frames {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
        for (name, run) in [("object", &object_run), ("image", &image_run)] {
            for (i, frame) in run.frames.iter().enumerate() {
                let file = dir.join(format!("{name}-{i:02}.png"));
                frame.save(&file).with_context(|| format!("writing {}", file.display()))?;
            }
            for (i, map) in run.difference_maps.iter().enumerate() {
                let file = dir.join(format!("{name}-difference-{:02}.png", i + 1));
                map.save(&file).with_context(|| format!("writing {}", file.display()))?;
            }
        }
    }
    let (object, image): (Flicker, Flicker) = (object_run.flicker(), image_run.flicker());
    let pair = |a: f64, b: f64| serde_json::json!({ "object_space": a, "image_space": b });
    if output.json {
        // Per consecutive frame pair, so a figure can be traced to a part of the path.
        let pairs: Vec<_> = object_run
            .differences
            .iter()
            .zip(&image_run.differences)
            .map(|(o, i)| {
                serde_json::json!({
                    "whole_frame": pair(o.mean(), i.mean()),
                    "terrain": pair(o.terrain_mean(), i.terrain_mean()),
                })
            })
            .collect();
        println!(
            "{}",
            serde_json::json!({
                "frames": path.len(), "width": width, "height": height,
                "whole_frame": pair(object.whole_frame, image.whole_frame),
                "terrain": pair(object.terrain, image.terrain),
                "terrain_ink": pair(object.terrain_ink, image.terrain_ink),
                "pairs": pairs,
            })
        );
    } else {
        println!("{} frames at {width}x{height}: mean motion-compensated luminance difference", path.len());
        println!("{:<14} {:>12} {:>12} {:>12}", "", "whole frame", "terrain", "terrain ink");
        for (name, f) in [("object-space", object), ("image-space", image)] {
            println!("{name:<14} {:>12.5} {:>12.5} {:>12.3}", f.whole_frame, f.terrain, f.terrain_ink);
        }
        let ratio = |a: f64, b: f64| if b > 0.0 { a / b } else { 0.0 };
        println!(
            "{:<14} {:>12.3} {:>12.3} {:>12.3}",
            "ratio",
            ratio(object.whole_frame, image.whole_frame),
            ratio(object.terrain, image.terrain),
            ratio(object.terrain_ink, image.terrain_ink)
        );
    }
    Ok(())
}

fn render(args: &RenderArgs) -> Result<()> {
    let mut styles = view_style(args.preset.as_deref(), args.style.as_deref(), &args.layer_style)?;
    let bar = LoadBar::start();
    let scene = load_scene(&args.scene, &bar)?;
    let camera = match &args.viewpoint {
        Some(name) => viewpoint_camera(&args.scene, name, &scene, &mut styles)?,
        None => camera(args, &scene)?,
    };
    let style = frame_style(&styles, &scene)?;
    let gpu = Arc::new(Gpu::new()?);
    let renderer = Renderer::with_options(gpu, &scene, &bar.render_options(&args.cache)?)?;
    bar.finish();
    let started = std::time::Instant::now();
    let data = data_view(&args.data)?;
    let frame = renderer.render(FrameRequest::new(&camera, &style, args.width, args.height).data(&data))?;
    let (image, stats) = (frame.image, frame.stats);
    info!(
        ms = started.elapsed().as_millis() as u64,
        triangles = stats.triangles,
        percent_of_source = stats.percent_drawn(),
        "rendered"
    );
    // The file's extension picks the format (`.jpg`/`.jpeg` as the server encodes JPEG, else PNG).
    let format = args.out.extension().and_then(|e| e.to_str()?.parse::<ImageFormat>().ok()).unwrap_or(ImageFormat::Png);
    let bytes = format.encode(&image, Some(JPEG_QUALITY))?;
    std::fs::write(&args.out, bytes).with_context(|| format!("cannot write {}", args.out.display()))?;
    println!("{}", args.out.display());
    Ok(())
}

/// JPEG quality of `landsketch render --out VIEW.jpg`.
const JPEG_QUALITY: u8 = 88;

/// The data layers of `--mappings` from the layer store in `--data-dir`; Table 9.1 warnings
/// and clamped times go to stderr.
fn data_view(args: &DataArgs) -> Result<DataView> {
    let Some(arg) = &args.mappings else { return Ok(DataView::default()) };
    let text = if arg.trim_start().starts_with('[') {
        arg.to_owned()
    } else {
        std::fs::read_to_string(arg).with_context(|| format!("cannot read mappings file {arg}"))?
    };
    let mappings: Vec<Mapping> = serde_json::from_str(&text).context("--mappings: invalid JSON")?;
    let store = Store::open(&args.data_dir)?;
    let request = DataRequest::resolve(&mappings, args.time.as_deref(), &store)?;
    for warning in &request.warnings {
        tracing::warn!("{warning}");
    }
    Ok(LayerCache::default().view(&request, &store)?)
}

/// The `N` comma-separated numbers of `flag`'s value, e.g. `--range 0,10`.
fn numbers<T: std::str::FromStr, const N: usize>(flag: &str, text: &str) -> Result<[T; N]> {
    let values: Vec<T> = text
        .split(',')
        .map(|s| s.trim().parse::<T>())
        .collect::<Result<_, _>>()
        .map_err(|_| anyhow::anyhow!("{flag} {text:?}: expected {N} comma-separated numbers"))?;
    values.try_into().map_err(|_| anyhow::anyhow!("{flag} {text:?}: expected {N} comma-separated numbers"))
}

fn legend(args: &LegendArgs) -> Result<()> {
    let kind: FieldKind = args.kind.parse()?;
    let mut options = LoadOptions::new(kind);
    options.variable = args.variable.clone();
    options.units = args.units.clone();
    options.crs = args.crs.as_deref().map(CrsDefinition::parse).transpose()?;
    let field = fields::load_file(&args.file, &options)?;
    let range = args.range.as_deref().map(|text| numbers::<f64, 2>("--range", text)).transpose()?;
    let map = args.colormap.as_deref().map(str::parse::<ColorMapName>).transpose()?;
    let ink = match (args.target.as_str(), &args.color) {
        ("hatch_color", Some(text)) => Some(numbers::<f32, 3>("--color", text)?),
        ("hatch_color", None) => Some(fields::HATCH_COLORS[0]),
        (_, Some(_)) => bail!("--color is the ink of --target hatch_color"),
        (_, None) => None,
    };
    let spec = ColorMapSpec { map, range, opacity: args.opacity, reverse: args.reverse, ink };
    let lut = Lut::for_field(&spec, &field)?;
    let title = match &args.title {
        Some(title) => title.clone(),
        None => args.file.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default(),
    };
    let legend = Legend::new(&title, kind, field.units(), field.classes(), &lut);
    std::fs::write(&args.out, legend.to_png()?).with_context(|| format!("cannot write {}", args.out.display()))?;
    let json_path = args.out.with_extension("json");
    std::fs::write(&json_path, serde_json::to_string_pretty(&legend)?)
        .with_context(|| format!("cannot write {}", json_path.display()))?;
    println!("{}\n{}", args.out.display(), json_path.display());
    Ok(())
}

fn serve(config: ServerConfig) -> Result<()> {
    if landsketch::api::config::admin_token_on_command_line(std::env::args_os()) {
        tracing::warn!(
            "--admin-token is visible in the process list to every user of this machine; \
             use --admin-token-file or LANDSKETCH_ADMIN_TOKEN instead"
        );
    }
    let runtime = tokio::runtime::Builder::new_multi_thread().enable_all().build()?;
    runtime.block_on(async {
        let server = Server::bind(config).await?;
        println!("landsketch: open {} in a browser", browser_url(server.local_addr()?));
        server.run(shutdown_signal()).await?;
        Ok(())
    })
}

/// The address of the browser UI of a server listening on `addr`: a server listening on every
/// interface (`0.0.0.0`, `::`) is opened on the loopback address.
fn browser_url(addr: std::net::SocketAddr) -> String {
    let mut addr = addr;
    if addr.ip().is_unspecified() {
        let loopback: std::net::IpAddr = match addr {
            std::net::SocketAddr::V4(_) => std::net::Ipv4Addr::LOCALHOST.into(),
            std::net::SocketAddr::V6(_) => std::net::Ipv6Addr::LOCALHOST.into(),
        };
        addr.set_ip(loopback);
    }
    format!("http://{addr}/")
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

fn bench(args: &BenchArgs) -> Result<()> {
    use landsketch::bench::{BenchOptions, run};
    let fields: PartialStyle = args.style.as_deref().map(json_object).transpose()?.unwrap_or_default();
    let styles = args
        .styles
        .iter()
        .map(|name| Ok((name.clone(), landsketch::render::presets::preset(name)?.with(&fields)?)))
        .collect::<Result<Vec<_>>>()?;
    let options =
        BenchOptions { frames: args.frames, width: args.width, height: args.height, step: args.step, path: args.path };
    let render_options = args.cache.render_options()?;
    let gpu = Arc::new(Gpu::new()?);
    let data = data_view(&args.data)?;
    let report =
        run(gpu, &args.scene, &args.plants, &styles, &data, &options, &render_options, |step| info!("{step}"))?;
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
        return Ok(());
    }
    println!(
        "{} ({}), {} x{} cores; {}x{}, {} frames, path {:?}; copy pass {:.1} ms",
        report.adapter,
        report.backend,
        report.cpu,
        report.cores,
        report.width,
        report.height,
        report.frames,
        report.path,
        report.copy_pass_ms.median
    );
    for scene in &report.scenes {
        println!(
            "\n{} plants, {} source triangles; prep {:.0} ms (cache {} hits, {} misses); peak RSS {:.0} MiB; GPU ~{:.0} MiB",
            scene.plants,
            scene.source_triangles,
            scene.prep_ms,
            scene.cache_hits,
            scene.cache_misses,
            scene.peak_rss_mib,
            scene.gpu_mib
        );
        for run in &scene.styles {
            let passes: Vec<String> = run.passes_ms.iter().map(|(k, v)| format!("{k} {:.1}", v.median)).collect();
            println!(
                "  {:<14} {:>6.1} ms ({:.1} fps, min {:.1}, max {:.1}); {} triangles = {:.2} % of source; {} plants {:?} ({} visited); {} mass domes; {} reference points; {}",
                run.style,
                run.frame_ms.median,
                run.fps,
                run.frame_ms.min,
                run.frame_ms.max,
                run.triangles,
                run.percent_drawn,
                run.plants_drawn,
                run.per_level,
                run.plants_visited,
                run.mass_domes,
                run.reference_points,
                passes.join(", ")
            );
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn render_args(args: &[&str]) -> RenderArgs {
        let cli = Cli::try_parse_from(["landsketch", "render"].iter().chain(args)).unwrap_or_else(|e| panic!("{e}"));
        match cli.command {
            Command::Render(args) => args,
            _ => panic!("not a render command"),
        }
    }

    #[test]
    fn negative_coordinates_are_values_not_flags() {
        let args = render_args(&["--pos", "-120,185", "--yaw", "-90", "--pitch", "-12.5", "--roll", "-3"]);
        assert_eq!(args.pos.as_deref(), Some("-120,185"));
        assert_eq!((args.yaw, args.pitch, args.roll), (Some(-90.0), Some(-12.5), Some(-3.0)));
        let args = render_args(&["--pos", "-120,-185,-2"]);
        assert_eq!(args.pos.as_deref(), Some("-120,-185,-2"));
        let args = render_args(&["--plan", "-50,-60,400", "--yaw", "-30"]);
        assert_eq!((args.plan.as_deref(), args.yaw), (Some("-50,-60,400"), Some(-30.0)));
        let cli = Cli::try_parse_from(["landsketch", "legend", "field.tif", "--range", "-5,5"]).unwrap();
        assert!(matches!(cli.command, Command::Legend(LegendArgs { range: Some(r), .. }) if r == "-5,5"));
    }

    #[test]
    fn style_flags_give_the_styles_a_request_body_gives() {
        let args = render_args(&[
            "--preset",
            "full_npr",
            "--style",
            r#"{"ambient": 0.4}"#,
            "--layer-style",
            r#"existing={"preset": "photorealism", "hatch_map": 1}"#,
        ]);
        let flags = view_style(args.preset.as_deref(), args.style.as_deref(), &args.layer_style).unwrap();
        let body = r#"{"preset": "full_npr", "style": {"ambient": 0.4},
            "layer_styles": {"existing": {"preset": "photorealism", "hatch_map": 1}}}"#;
        assert_eq!(flags, serde_json::from_str::<ViewStyle>(body).unwrap());
        let err = view_style(None, None, &[r#"existing={"colour": 1}"#.to_owned()]).unwrap_err();
        assert!(
            format!("{err:#}").contains("--layer-style existing") && format!("{err:#}").contains("colour"),
            "{err:#}"
        );
    }

    #[test]
    fn the_browser_url_is_the_bound_address_or_loopback() {
        assert_eq!(browser_url("127.0.0.1:8080".parse().unwrap()), "http://127.0.0.1:8080/");
        assert_eq!(browser_url("0.0.0.0:9000".parse().unwrap()), "http://127.0.0.1:9000/");
        assert_eq!(browser_url("[::]:9000".parse().unwrap()), "http://[::1]:9000/");
        assert_eq!(browser_url("192.168.1.5:80".parse().unwrap()), "http://192.168.1.5:80/");
    }
}
