//! `landsketch bench` (SPEC O3): renders scenes of 100 … 1,000,000 plants generated from the
//! sample scene's placement rules along a short walk at eye height or a bird's-eye flight, in
//! several styles, and
//! reports per-pass times (median/min/max over the frames), triangles submitted, the share of
//! the source geometry drawn (the seeds' "% lod", thesis Table 8.1), preprocessing time, peak
//! RSS and an estimate of GPU memory. No figure here is asserted anywhere; it is measured.

use crate::render::projection::DataView;
use crate::render::{FrameRequest, Gpu, RenderError, RenderOptions, Renderer, Style};
use crate::scene::camera::Camera;
use crate::scene::config::SceneConfig;
use crate::scene::{Scene, SceneError};
use serde::Serialize;
use std::collections::BTreeMap;
use std::path::Path;
use std::sync::Arc;
use std::time::Instant;

/// Errors of a benchmark run.
#[derive(Debug, thiserror::Error)]
pub enum BenchError {
    #[error(transparent)]
    Scene(#[from] SceneError),
    #[error(transparent)]
    Render(#[from] RenderError),
    #[error("encoding a frame failed: {0}")]
    Encode(#[from] image::ImageError),
    #[error("the sample scene's rules cannot place {target} plants (got {placed})")]
    Size { target: usize, placed: usize },
}

/// What to measure.
#[derive(Debug, Clone)]
pub struct BenchOptions {
    /// Frames measured per scene and style (after one warm-up frame).
    pub frames: usize,
    pub width: u32,
    pub height: u32,
    /// Metres the camera moves forward per frame.
    pub step: f32,
    /// The camera's path.
    pub path: BenchPath,
}

/// The camera path of a benchmark.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, clap::ValueEnum)]
#[serde(rename_all = "snake_case")]
pub enum BenchPath {
    /// From the scene's default camera forward at its eye height above the terrain.
    Walk,
    /// From [`BIRDS_EYE_HEIGHT`] above the default camera's ground, looking 35° down, flying
    /// forward along its heading at a constant height.
    BirdsEye,
}

/// Height of the bird's-eye path above the ground under the default camera (metres).
pub const BIRDS_EYE_HEIGHT: f32 = 300.0;
/// Pitch of the bird's-eye path (degrees).
const BIRDS_EYE_PITCH: f32 = -35.0;

/// Median, minimum and maximum of a series, in milliseconds.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct Stat {
    pub median: f64,
    pub min: f64,
    pub max: f64,
}

impl Stat {
    /// Summarises `values` (empty → zeros).
    pub fn of(values: &[f64]) -> Stat {
        let mut v = values.to_vec();
        v.sort_by(f64::total_cmp);
        match v.len() {
            0 => Stat::default(),
            n => Stat {
                median: if n % 2 == 1 { v[n / 2] } else { 0.5 * (v[n / 2 - 1] + v[n / 2]) },
                min: v[0],
                max: v[n - 1],
            },
        }
    }
}

/// The figures of one style on one scene.
#[derive(Debug, Clone, Serialize)]
pub struct StyleRun {
    pub style: String,
    /// Whole frames as the server renders them (no per-pass synchronisation), encode included.
    pub frame_ms: Stat,
    /// Frames per second from the median frame.
    pub fps: f64,
    /// Per pass, measured in separate frames that wait for the GPU after every pass:
    /// `cull` (CPU: frustum culling, LOD selection, reference update, upload), `geometry`,
    /// `prefilter`, `contour`, `data`, `compose`, `readback`, and `encode` (JPEG, quality 80).
    pub passes_ms: BTreeMap<String, Stat>,
    pub triangles: u64,
    pub percent_drawn: f64,
    pub plants_drawn: u64,
    /// Plant draws per level of detail (full, HLP billboards, plant billboard).
    pub per_level: [u64; 3],
    /// Hatching reference points of the frame (HLPs near, plants, terrain-grid cells far).
    pub reference_points: u64,
    /// Plants culling looked at one by one (those of the plant clusters it opened).
    pub plants_visited: u64,
    /// Domes of vegetation masses drawn.
    pub mass_domes: u64,
}

/// The figures of one scene size.
#[derive(Debug, Clone, Serialize)]
pub struct SceneRun {
    pub plants: usize,
    pub source_triangles: u64,
    /// Building the renderer: HLPs, billboard baking (or loading them from the cache), upload.
    pub prep_ms: f64,
    pub cache_hits: u64,
    pub cache_misses: u64,
    /// Peak resident memory of the process after this scene (MiB).
    pub peak_rss_mib: f64,
    /// GPU memory of the scene and one frame's targets (MiB, estimated from sizes).
    pub gpu_mib: f64,
    pub styles: Vec<StyleRun>,
}

/// A whole benchmark report.
#[derive(Debug, Clone, Serialize)]
pub struct BenchReport {
    pub adapter: String,
    pub backend: String,
    pub cpu: String,
    pub cores: usize,
    pub width: u32,
    pub height: u32,
    pub frames: usize,
    /// The camera path.
    pub path: BenchPath,
    /// A plain full-screen copy pass at the same size: the floor of any post pass.
    pub copy_pass_ms: Stat,
    pub scenes: Vec<SceneRun>,
}

/// The sample scene with every rule's density scaled so that about `target` plants are placed
/// (and, above the scene's own densities, its minimum spacing by the square root of the factor).
pub fn scaled_scene(path: &Path, target: usize) -> Result<Scene, BenchError> {
    let base = SceneConfig::load(path)?;
    let build = |factor: f64| -> Result<Scene, BenchError> {
        let mut config = base.clone();
        for rule in config.layers.iter_mut().flat_map(|l| l.rules.iter_mut()) {
            rule.density = (rule.density * factor).min(10_000.0);
            // Denser than the scene's rules: the spacing shrinks with the density, else the
            // minimum spacing caps the count (forest rules sit near their packing limit).
            if factor > 1.0 {
                rule.min_spacing /= factor.sqrt();
            }
        }
        Ok(Scene::from_config_file(&config, path, &crate::progress::Silent)?)
    };
    let mut factor = 1.0;
    let mut scene = build(factor)?;
    // Placement is a jittered grid with minimum spacing: counts grow sublinearly with density,
    // so correct the factor a few times.
    for _ in 0..4 {
        let placed = scene.plant_count();
        if placed == 0 {
            return Err(BenchError::Size { target, placed });
        }
        let ratio = target as f64 / placed as f64;
        if (ratio - 1.0).abs() < 0.03 {
            break;
        }
        factor *= ratio;
        scene = build(factor)?;
    }
    let placed = scene.plant_count();
    if (placed as f64 - target as f64).abs() > 0.1 * target as f64 {
        return Err(BenchError::Size { target, placed });
    }
    Ok(scene)
}

/// The cameras of `path`: from the default camera forward along its heading, on the walk with
/// its eye height kept above the terrain, on the bird's-eye path at a constant height.
fn cameras(scene: &Scene, frames: usize, step: f32, path: BenchPath) -> Vec<Camera> {
    let start = scene.default_camera;
    let ground_at = |x: f32, y: f32| scene.terrain.height_at(f64::from(x), f64::from(y)).map(|g| g as f32);
    let start_ground = ground_at(start.position[0], start.position[1]);
    let eye_height = start_ground.map_or(1.7, |ground| start.position[2] - ground);
    let flight_z = start_ground.map_or(start.position[2], |g| g + BIRDS_EYE_HEIGHT);
    let heading = start.yaw.to_radians();
    (0..frames)
        .map(|i| {
            let d = step * i as f32;
            let (x, y) = (start.position[0] + heading.sin() * d, start.position[1] + heading.cos() * d);
            match path {
                BenchPath::Walk => {
                    let z = ground_at(x, y).map_or(start.position[2], |g| g + eye_height);
                    Camera { position: [x, y, z], ..start }
                }
                BenchPath::BirdsEye => Camera { position: [x, y, flight_z], pitch: BIRDS_EYE_PITCH, ..start },
            }
        })
        .collect()
}

/// Encodes a frame as the server does (JPEG, quality 80); returns its size in bytes.
fn encode_jpeg(image: &image::RgbaImage) -> Result<usize, image::ImageError> {
    Ok(crate::render::image_format::ImageFormat::Jpeg.encode(image, Some(80))?.len())
}

/// A memory figure of this process from `/proc/self/status` in MiB (Linux; `None` elsewhere):
/// `VmHWM` (peak) or `VmRSS` (now).
fn status_mib(key: &str) -> Option<f64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let kib: f64 = status.lines().find_map(|l| l.strip_prefix(key))?.split_whitespace().next()?.parse().ok()?;
    Some(kib / 1024.0)
}

/// Peak resident set size of this process in MiB (Linux; 0 elsewhere).
pub fn peak_rss_mib() -> f64 {
    status_mib("VmHWM:").unwrap_or(0.0)
}

/// Resident set size of this process now, in MiB (Linux; `None` elsewhere): the before /
/// during / after figures of the server benchmarks and the memory tests.
pub fn rss_mib() -> Option<f64> {
    status_mib("VmRSS:")
}

/// The `p`-quantile (0…1, nearest rank) of ascending `sorted` values; NaN when empty.
pub fn percentile(sorted: &[f64], p: f64) -> f64 {
    if sorted.is_empty() {
        return f64::NAN;
    }
    sorted[((sorted.len() - 1) as f64 * p).round() as usize]
}

/// The CPU model name (Linux; "unknown" elsewhere).
fn cpu_name() -> String {
    std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("model name"))
                .and_then(|l| l.split(':').nth(1))
                .map(|s| s.trim().to_owned())
        })
        .unwrap_or_else(|| "unknown".into())
}

/// Measures one style on one renderer along `cameras`.
fn run_style(
    renderer: &Renderer,
    name: &str,
    style: &Style,
    data: &DataView,
    cameras: &[Camera],
    options: &BenchOptions,
) -> Result<StyleRun, BenchError> {
    let (w, h) = (options.width, options.height);
    // Warm-up: pipelines, first-use allocations.
    renderer.render(FrameRequest::new(&cameras[0], style, w, h).data(data))?;
    // The walk is rendered as a session would: the hatching follows the camera (eq. 6.2).
    let mut state = renderer.new_view_state();
    let mut frames = Vec::with_capacity(cameras.len());
    for camera in cameras {
        let started = Instant::now();
        let frame = renderer.render(FrameRequest::new(camera, style, w, h).data(data).history(&mut state))?;
        encode_jpeg(&frame.image)?;
        frames.push(started.elapsed().as_secs_f64() * 1e3);
    }
    let mut state = renderer.new_view_state();
    let mut passes: BTreeMap<String, Vec<f64>> = BTreeMap::new();
    for camera in cameras {
        let frame =
            renderer.render(FrameRequest::new(camera, style, w, h).data(data).history(&mut state).profiled())?;
        let image = frame.image;
        for (pass, ms) in frame.times.unwrap_or_default() {
            passes.entry(pass.to_owned()).or_default().push(ms);
        }
        let started = Instant::now();
        encode_jpeg(&image)?;
        passes.entry("encode".into()).or_default().push(started.elapsed().as_secs_f64() * 1e3);
    }
    // What this style draws (leaf particles and substitution shapes change the triangles).
    let stats = renderer.draw_stats(&FrameRequest::new(&cameras[cameras.len() / 2], style, w, h))?;
    let frame_ms = Stat::of(&frames);
    Ok(StyleRun {
        style: name.to_owned(),
        fps: 1e3 / frame_ms.median.max(1e-9),
        frame_ms,
        passes_ms: passes.iter().map(|(k, v)| (k.clone(), Stat::of(v))).collect(),
        triangles: stats.triangles,
        percent_drawn: stats.percent_drawn(),
        plants_drawn: stats.plants_drawn,
        per_level: stats.per_level,
        reference_points: stats.reference_points,
        plants_visited: stats.plants_visited,
        mass_domes: stats.mass_domes,
    })
}

/// Runs the benchmark: for each plant count a scene from `scene_path`'s rules, for each of
/// `styles` the frames of [`BenchOptions`], and when `data` has mappings the same frames again
/// with its data layers (a style named `… + data`), so the two compare within one run.
/// `render_options` are the renderer's (its preprocessing cache: the first run bakes, later
/// runs load; the level-of-detail thresholds).
#[allow(clippy::too_many_arguments)]
pub fn run(
    gpu: Arc<Gpu>,
    scene_path: &Path,
    plant_counts: &[usize],
    styles: &[(String, Style)],
    data: &DataView,
    options: &BenchOptions,
    render_options: &RenderOptions,
    mut progress: impl FnMut(&str),
) -> Result<BenchReport, BenchError> {
    let mut scenes = Vec::new();
    let mut copy_pass_ms = Stat::default();
    for &plants in plant_counts {
        progress(&format!("generating the {plants}-plant scene"));
        let scene = scaled_scene(scene_path, plants)?;
        let cameras = cameras(&scene, options.frames.max(1), options.step, options.path);
        let cache = render_options.cache.as_ref();
        let before = cache.map(|c| c.stats()).unwrap_or_default();
        let started = Instant::now();
        let renderer = Renderer::with_options(gpu.clone(), &scene, render_options)?;
        let prep_ms = started.elapsed().as_secs_f64() * 1e3;
        let after = cache.map(|c| c.stats()).unwrap_or_default();
        if scenes.is_empty() {
            copy_pass_ms = Stat::of(&renderer.time_copy_pass(options.width, options.height, options.frames.max(1))?);
        }
        let mut runs = Vec::new();
        let views = std::iter::once((String::new(), DataView::default()))
            .chain((!data.mappings.is_empty()).then(|| (" + data".to_owned(), data.clone())));
        for (suffix, data) in views {
            for (name, style) in styles {
                progress(&format!("{} plants, style {name}{suffix}", scene.plant_count()));
                runs.push(run_style(&renderer, &format!("{name}{suffix}"), style, &data, &cameras, options)?);
            }
        }
        scenes.push(SceneRun {
            plants: scene.plant_count(),
            source_triangles: renderer
                .draw_stats(&FrameRequest::new(&cameras[0], Style::default(), options.width, options.height))?
                .source_triangles,
            prep_ms,
            cache_hits: after.hits - before.hits,
            cache_misses: after.misses - before.misses,
            peak_rss_mib: peak_rss_mib(),
            gpu_mib: renderer.gpu_bytes(options.width, options.height) as f64 / (1024.0 * 1024.0),
            styles: runs,
        });
    }
    Ok(BenchReport {
        adapter: gpu.adapter_info.name.clone(),
        backend: format!("{:?}", gpu.adapter_info.backend),
        cpu: cpu_name(),
        cores: std::thread::available_parallelism().map_or(1, |n| n.get()),
        width: options.width,
        height: options.height,
        frames: options.frames,
        path: options.path,
        copy_pass_ms,
        scenes,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stats_are_median_min_max() {
        assert_eq!(Stat::of(&[3.0, 1.0, 2.0]), Stat { median: 2.0, min: 1.0, max: 3.0 });
        assert_eq!(Stat::of(&[4.0, 1.0, 2.0, 3.0]).median, 2.5);
        assert_eq!(Stat::of(&[]), Stat::default());
    }

    #[test]
    fn the_paths_walk_at_eye_height_and_fly_at_a_constant_height() {
        let scene = scaled_scene(Path::new("data/boulder/scene.toml"), 100).unwrap();
        let start = scene.default_camera;
        let ground = |c: &Camera| scene.terrain.height_at(f64::from(c.position[0]), f64::from(c.position[1]));
        let start_ground = ground(&start).unwrap() as f32;
        let walk = cameras(&scene, 4, 10.0, BenchPath::Walk);
        let flight = cameras(&scene, 4, 10.0, BenchPath::BirdsEye);
        for (i, (w, f)) in walk.iter().zip(&flight).enumerate() {
            // Both move 10 m a frame along the default heading.
            let moved = glam::Vec2::new(w.position[0] - start.position[0], w.position[1] - start.position[1]).length();
            assert!((moved - 10.0 * i as f32).abs() < 1e-3, "frame {i}: {moved}");
            assert_eq!((w.position[0], w.position[1]), (f.position[0], f.position[1]));
            let eye = w.position[2] - ground(w).unwrap() as f32;
            assert!((eye - (start.position[2] - start_ground)).abs() < 1e-3 && w.pitch == start.pitch);
            assert!((f.position[2] - (start_ground + BIRDS_EYE_HEIGHT)).abs() < 1e-3 && f.pitch == BIRDS_EYE_PITCH);
        }
    }

    #[test]
    fn scaled_scenes_reach_their_plant_count() {
        let path = Path::new("data/boulder/scene.toml");
        for target in [100, 1000] {
            let scene = scaled_scene(path, target).unwrap();
            let placed = scene.plant_count() as f64;
            assert!((placed - target as f64).abs() <= 0.1 * target as f64, "{target}: {placed}");
        }
    }
}
