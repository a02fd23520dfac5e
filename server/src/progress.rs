//! Progress of getting a scene on screen — reading the terrain, draping the land cover,
//! placing the plants, preprocessing them for the renderer — reported by the scene loader and
//! the renderer, shown as a progress bar by the command line and as the loading stage of
//! `GET /api/health` by the server.

use serde::Serialize;
use std::sync::Mutex;

/// A step of loading a scene, in the order they run.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, utoipa::ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum Stage {
    /// Reading the DEM and building the terrain mesh.
    Terrain,
    /// Reading the land cover or orthophoto laid on the ground.
    Drape,
    /// Placing the plants of the vegetation layers.
    Placement,
    /// HLPs, billboards and vegetation masses of the renderer, terrain lines, upload.
    Preprocessing,
}

impl Stage {
    /// What the stage does, in words for people waiting.
    pub fn label(self) -> &'static str {
        match self {
            Stage::Terrain => "reading the terrain",
            Stage::Drape => "draping the land cover",
            Stage::Placement => "placing the plants",
            Stage::Preprocessing => "preparing the plants for drawing",
        }
    }

    /// The share of a whole load at which the stage starts and ends: fixed estimates from the
    /// sample scenes (preprocessing takes the longest, reading the terrain the least).
    fn span(self) -> (f32, f32) {
        match self {
            Stage::Terrain => (0.0, 0.1),
            Stage::Drape => (0.1, 0.2),
            Stage::Placement => (0.2, 0.5),
            Stage::Preprocessing => (0.5, 1.0),
        }
    }

    /// Percent of the whole load done when `fraction` (0..=1) of this stage is.
    pub fn percent(self, fraction: f32) -> f32 {
        let (start, end) = self.span();
        100.0 * (start + (end - start) * fraction.clamp(0.0, 1.0))
    }
}

/// Receives the progress of a load: `fraction` (0..=1) of `stage` is done.
pub trait Progress: Send + Sync + std::fmt::Debug {
    fn report(&self, stage: Stage, fraction: f32);
}

/// Progress nobody watches.
#[derive(Debug, Clone, Copy, Default)]
pub struct Silent;

impl Progress for Silent {
    fn report(&self, _: Stage, _: f32) {}
}

/// The latest progress of a load, kept for readers on other threads (the server's health
/// endpoint); stage changes are logged.
#[derive(Debug, Default)]
pub struct LoadProgress {
    latest: Mutex<Option<(Stage, f32)>>,
}

impl LoadProgress {
    /// The stage reached and the percent of the whole load done; `None` before the first
    /// report.
    pub fn current(&self) -> Option<(Stage, f32)> {
        let latest = *self.latest.lock().unwrap_or_else(|e| e.into_inner());
        latest.map(|(stage, fraction)| (stage, stage.percent(fraction)))
    }
}

impl Progress for LoadProgress {
    fn report(&self, stage: Stage, fraction: f32) {
        let mut latest = self.latest.lock().unwrap_or_else(|e| e.into_inner());
        if latest.is_none_or(|(previous, _)| previous != stage) {
            tracing::info!(stage = stage.label(), "loading");
        }
        *latest = Some((stage, fraction));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn percent_rises_through_the_stages() {
        let order = [Stage::Terrain, Stage::Drape, Stage::Placement, Stage::Preprocessing];
        let percents: Vec<f32> = order.iter().flat_map(|s| [s.percent(0.0), s.percent(0.5), s.percent(1.0)]).collect();
        assert!(percents.windows(2).all(|w| w[0] <= w[1]), "{percents:?}");
        assert_eq!((percents[0], percents[percents.len() - 1]), (0.0, 100.0));
        let progress = LoadProgress::default();
        assert_eq!(progress.current(), None);
        progress.report(Stage::Placement, 0.5);
        let (stage, percent) = progress.current().expect("reported");
        assert!(stage == Stage::Placement && (percent - 35.0).abs() < 1e-3, "{stage:?} {percent}");
    }
}
