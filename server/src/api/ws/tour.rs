//! Tours in a WebSocket session: the session's camera flies through viewpoints in order
//! ([`crate::scene::tour`]), rendered as the session's own frames (so the hatching follows
//! the camera coherently from frame to frame), with a `tour` message at each viewpoint. In a
//! meeting the presenter's tour is what the followers see, and each viewpoint's caption
//! becomes the meeting's caption.

use super::{ServerMessage, Session};
use crate::api::Ready;
use crate::api::error::ApiError;
use crate::api::meetings;
use crate::api::view::{CameraParams, Source};
use crate::fields::Mapping;
use crate::render::style::{LayerStyle, PartialStyle};
use crate::render::view_style::ViewStyle;
use crate::scene::tour::{Tour, TourPace};
use crate::store::request::DataRequest;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::time::Duration;
use tokio::time::Instant;
use utoipa::ToSchema;

/// Most viewpoints in one tour.
pub const MAX_TOUR_STOPS: usize = 100;

/// What a `tour` control does.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum TourAction {
    /// Starts a tour of `viewpoints` (from viewpoint `from`, default 0).
    Start,
    /// Stops the tour where the camera is.
    Stop,
    /// Flies on to the next viewpoint now.
    Next,
    /// Flies back to the previous viewpoint.
    Previous,
}

/// One viewpoint of a tour.
#[derive(Debug, Clone, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct TourViewpoint {
    /// The camera, as in a `camera` message (over the scene's default camera).
    pub camera: CameraParams,
    /// A short name.
    #[serde(default)]
    pub name: Option<String>,
    /// The caption sent when the camera arrives (plain text, at most 500 characters).
    #[serde(default)]
    pub caption: Option<String>,
    /// The look the view takes on arrival, as in a `style` control with `replace`: a preset,
    /// style fields over it, styles of single layers (none of the three: the look stays).
    #[serde(default)]
    pub preset: Option<String>,
    #[serde(default)]
    #[schema(value_type = Option<Object>)]
    pub style: Option<PartialStyle>,
    #[serde(default)]
    #[schema(value_type = Option<Object>)]
    pub layer_styles: Option<BTreeMap<String, LayerStyle>>,
    /// The data layers the view shows on arrival, as in a `data` control (absent: unchanged).
    #[serde(default)]
    pub mappings: Option<Vec<Mapping>>,
    /// The data layers' time (ISO 8601).
    #[serde(default)]
    pub time: Option<String>,
}

/// The `tour` control message.
#[derive(Debug, Clone, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct TourControl {
    /// `start`, `stop`, `next` or `previous`.
    pub action: TourAction,
    /// `start`: the viewpoints in order (1 to 100); none: the planner's viewpoints (the scene
    /// file's, then the admin API's, as `GET /api/viewpoints` lists them).
    #[serde(default)]
    pub viewpoints: Vec<TourViewpoint>,
    /// `start`: the viewpoint to fly to first (default 0).
    #[serde(default)]
    pub from: Option<usize>,
    /// `start`: seconds the camera rests at each viewpoint (0–600, default 4).
    #[serde(default)]
    pub dwell_s: Option<f32>,
    /// `start`: seconds of every flight between viewpoints (0.1–120; default from the
    /// distance at 60 m/s and the turn at 45°/s, 2–10 s).
    #[serde(default)]
    pub leg_s: Option<f32>,
}

/// What a `tour` message reports.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum TourEvent {
    /// The camera flies to viewpoint `index`.
    Flying,
    /// The camera reached viewpoint `index`; its caption is shown.
    Arrived,
    /// The tour is over (after the rest at the last viewpoint).
    Finished,
    /// The tour was stopped (a `stop` control, or a camera control took over).
    Stopped,
}

struct Stop {
    name: Option<String>,
    caption: Option<String>,
    eye_height: Option<f32>,
    /// The look taken on arrival (checked when the tour starts).
    look: Option<ViewStyle>,
    /// The data layers shown on arrival (resolved when the tour starts).
    data: Option<DataRequest>,
}

/// A tour being played by a session.
pub(super) struct TourPlay {
    tour: Tour,
    /// When the tour's clock started.
    clock: Instant,
    stops: Vec<Stop>,
    /// When the session must look at the tour again.
    pub(super) wake: Option<Instant>,
}

impl TourPlay {
    fn seconds(&self, now: Instant) -> f32 {
        now.saturating_duration_since(self.clock).as_secs_f32()
    }

    fn message(&self, event: TourEvent, index: usize) -> ServerMessage {
        let stop = self.stops.get(index);
        ServerMessage::Tour {
            event,
            index,
            count: self.stops.len(),
            name: stop.and_then(|s| s.name.clone()),
            caption: stop.and_then(|s| s.caption.clone()),
        }
    }
}

fn seconds(value: Option<f32>, parameter: &str, range: std::ops::RangeInclusive<f32>) -> Result<Option<f32>, ApiError> {
    match value {
        Some(v) if !range.contains(&v) => {
            Err(ApiError::invalid(parameter, format!("{parameter} {v} is outside {}–{}", range.start(), range.end())))
        }
        other => Ok(other),
    }
}

/// The terrain height under a scene point.
fn ground(ready: &Ready) -> impl Fn(f32, f32) -> Option<f32> + '_ {
    |x, y| ready.scene.terrain.height_at(f64::from(x), f64::from(y)).map(|g| g as f32)
}

impl Session<'_> {
    /// Applies a `tour` control.
    pub(super) async fn tour_control(&mut self, control: TourControl, now: Instant) -> Result<ServerMessage, ApiError> {
        if control.action == TourAction::Start {
            return self.start_tour(control, now).await;
        }
        if control.action == TourAction::Stop {
            return self.stop_tour().ok_or_else(|| ApiError::Conflict("no tour is playing".into()));
        }
        let Some(play) = &mut self.tour else { return Err(ApiError::Conflict("no tour is playing".into())) };
        let current = play.tour.current();
        let target = match control.action {
            TourAction::Next => current + 1,
            _ => current
                .checked_sub(1)
                .ok_or_else(|| ApiError::invalid("action", "the tour is at its first viewpoint"))?,
        };
        let t = play.seconds(now);
        if !play.tour.go_to(target, self.view.camera, t, &ground(self.ready)) {
            return Err(ApiError::invalid("action", "the tour is at its last viewpoint"));
        }
        play.wake = Some(now);
        Ok(play.message(TourEvent::Flying, target))
    }

    async fn start_tour(&mut self, mut control: TourControl, now: Instant) -> Result<ServerMessage, ApiError> {
        if control.viewpoints.is_empty() {
            control.viewpoints = crate::api::viewpoints::all(self.state)
                .await?
                .into_iter()
                .map(|listed| {
                    let v = listed.viewpoint;
                    TourViewpoint {
                        camera: v.camera,
                        name: Some(v.name),
                        caption: Some(v.caption).filter(|c| !c.is_empty()),
                        preset: v.preset,
                        style: v.style,
                        layer_styles: v.layer_styles,
                        mappings: v.mappings,
                        time: v.time,
                    }
                })
                .collect();
        }
        let count = control.viewpoints.len();
        if !(1..=MAX_TOUR_STOPS).contains(&count) {
            return Err(ApiError::invalid(
                "viewpoints",
                format!("a tour has 1 to {MAX_TOUR_STOPS} viewpoints, not {count}"),
            ));
        }
        let scene = &self.ready.scene;
        let mut cameras = Vec::with_capacity(count);
        let mut stops = Vec::with_capacity(count);
        for (i, viewpoint) in control.viewpoints.into_iter().enumerate() {
            let resolved = viewpoint.camera.resolve(&scene.default_camera, scene, Source::Message).map_err(|e| {
                ApiError::invalid(
                    format!("viewpoints[{i}].camera.{}", e.parameter),
                    format!("viewpoint {i}: {}", e.message),
                )
            })?;
            cameras.push(resolved.camera);
            let styled = viewpoint.preset.is_some() || viewpoint.style.is_some() || viewpoint.layer_styles.is_some();
            let look = styled.then(|| ViewStyle {
                preset: viewpoint.preset,
                style: viewpoint.style.unwrap_or_default(),
                layer_styles: viewpoint.layer_styles.unwrap_or_default(),
            });
            if let Some(look) = &look {
                look.resolve(&scene.layer_names())
                    .map_err(|e| ApiError::invalid(format!("viewpoints[{i}].style"), format!("viewpoint {i}: {e}")))?;
            }
            let data = match &viewpoint.mappings {
                Some(mappings) => {
                    Some(DataRequest::resolve(mappings, viewpoint.time.as_deref(), self.state.store()).map_err(
                        |e| ApiError::invalid(format!("viewpoints[{i}].mappings"), format!("viewpoint {i}: {e}")),
                    )?)
                }
                None => None,
            };
            stops.push(Stop {
                name: meetings::caption(viewpoint.name, &format!("viewpoints[{i}].name"))?,
                caption: meetings::caption(viewpoint.caption, &format!("viewpoints[{i}].caption"))?,
                eye_height: resolved.eye_height,
                look,
                data,
            });
        }
        let from = control.from.unwrap_or(0);
        if from >= count {
            return Err(ApiError::invalid("from", format!("from {from} is not one of the {count} viewpoints")));
        }
        let defaults = TourPace::default();
        let dwell_s = seconds(control.dwell_s, "dwell_s", 0.0..=600.0)?.unwrap_or(defaults.dwell_s);
        let leg_s = seconds(control.leg_s, "leg_s", 0.1..=120.0)?.map_or(defaults.leg_s, |s| (s, s));
        let pace = TourPace { dwell_s, leg_s, ..defaults };
        let tour = Tour::start(cameras, from, self.view.camera, &ground(self.ready), pace, 0.0)
            .unwrap_or_else(|| unreachable!("`from` is one of the viewpoints"));
        let play = TourPlay { tour, clock: now, stops, wake: Some(now) };
        let message = play.message(TourEvent::Flying, from);
        self.tour = Some(play);
        Ok(message)
    }

    /// Stops the tour, if one plays: the `tour` message saying so.
    pub(super) fn stop_tour(&mut self) -> Option<ServerMessage> {
        let play = self.tour.take()?;
        Some(play.message(TourEvent::Stopped, play.tour.current()))
    }

    /// Moves the tour on to `now`: sets the camera, marks the view as moving while the camera
    /// flies (interactive frames), and returns the `tour` messages of viewpoints reached.
    pub(super) fn advance_tour(&mut self, now: Instant, frame_interval: Duration) -> Vec<ServerMessage> {
        let Some(play) = &mut self.tour else { return Vec::new() };
        let step = play.tour.advance(play.seconds(now), &ground(self.ready));
        let mut messages = Vec::new();
        self.view.camera = step.camera;
        if step.moving {
            self.view.eye_height = None;
            self.last_control = Some(now);
        }
        play.wake = match (step.moving, step.next_change) {
            (true, _) => Some(now + frame_interval),
            (false, Some(at)) => Some(play.clock + Duration::from_secs_f32(at.max(0.0))),
            (false, None) => None,
        };
        let mut caption = None;
        let mut arrival = None;
        if let Some(index) = step.reached {
            let stop = &play.stops[index];
            self.view.eye_height = stop.eye_height;
            messages.push(play.message(TourEvent::Arrived, index));
            caption = Some(stop.caption.clone());
            arrival = Some((stop.look.clone(), stop.data.clone()));
        }
        if step.finished {
            messages.push(play.message(TourEvent::Finished, play.tour.current()));
            self.tour = None;
        }
        if let Some(caption) = caption {
            self.caption_for_followers(caption);
        }
        // The viewpoint's look and data layers, as `style` and `data` controls would set them.
        if let Some((look, data)) = arrival {
            if let Some(look) = look {
                match self.set_style(&look, true) {
                    Ok(styles) => messages
                        .push(ServerMessage::Style { style: styles.base.clone(), layer_styles: styles.layers.clone() }),
                    Err(error) => tracing::warn!(session = self.id, %error, "a tour viewpoint's look was refused"),
                }
            }
            if let Some(data) = data {
                messages.push(ServerMessage::Data { time: data.time.clone(), warnings: data.warnings.clone() });
                self.view.data = data;
            }
        }
        messages
    }
}
