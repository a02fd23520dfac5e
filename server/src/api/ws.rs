//! WebSocket sessions (`GET /api/ws`): clients send JSON control messages, the server answers
//! with JSON status messages and binary frames (a [`HEADER_LEN`]-byte header, then the image).
//!
//! Latest wins: a session has at most one render queued or running; controls that arrive
//! meanwhile replace the queued view, and when a frame is done the newest view is rendered
//! next. While the camera or style changes, frames are smaller and JPEG at a lower quality
//! (`--interactive-scale`, `--interactive-quality`, at most `--max-fps`); after
//! `--still-delay-ms` of rest the session gets a full-size still in its own format.

mod meeting;
mod tour;

pub use meeting::MeetingRole;
pub use tour::{TourAction, TourControl, TourEvent, TourViewpoint};

use super::auth::Admin;
use super::connections::stopped;
use super::error::{ApiError, ErrorDetail};
use super::events::Changed;
use super::meetings::{Mailbox, Presenter};
use super::metrics::Metrics;
use super::pool::{Frame, FrameKind, FrameReceiver, PoolError, SessionLane};
use super::routes::{CameraInfo, pool_error};
use super::view::{
    CameraParams, DEFAULT_JPEG_QUALITY, ImageFormat, RenderQuery, Source, ViewParams, ViewRequest, check_compare,
    image_format, image_side, jpeg_quality,
};
use super::{AppState, Ready};
use crate::fields::Mapping;
use crate::render::Style;
use crate::render::compare::Compare;
use crate::render::marks::Pin;
use crate::render::style::{FrameStyle, LayerStyle, PartialStyle};
use crate::render::view_style::ViewStyle;
use crate::scene::camera::Camera;
use crate::scene::camera_params::DEFAULT_EYE_HEIGHT;
use crate::store::request::DataRequest;
use axum::body::Bytes;
use axum::extract::ws::{CloseFrame, Message, Utf8Bytes, WebSocket, WebSocketUpgrade, close_code};
use axum::extract::{RawQuery, State};
use axum::response::Response;
use serde::{Deserialize, Serialize};
use serde_json::Value;
use std::collections::BTreeMap;
use std::time::Duration;
use tokio::time::Instant;
use utoipa::ToSchema;

/// Length of the binary frame header.
pub const HEADER_LEN: usize = 20;
/// First two bytes of every binary frame.
pub const MAGIC: [u8; 2] = *b"LS";
/// Version of the frame header and message protocol.
pub const PROTOCOL_VERSION: u8 = 1;
/// Longest a server waits for sessions to close at shutdown.
pub const CLOSE_GRACE: Duration = Duration::from_secs(5);
/// Longest a session waits for a client to take its close frame.
const CLOSE_SEND_TIMEOUT: Duration = Duration::from_secs(1);
/// How long a session closed for an oversized message (code 1009) keeps the connection, so
/// that the close frame reaches the client before the unread rest resets the connection.
const CLOSE_LINGER: Duration = Duration::from_millis(250);

/// A relative camera move: translation along the heading, then rotation.
#[derive(Debug, Clone, Copy, Default, Deserialize, ToSchema)]
#[serde(default, deny_unknown_fields)]
pub struct Move {
    /// Metres along the (new) heading, horizontally.
    pub forward: f32,
    /// Metres to the right of the heading.
    pub right: f32,
    /// Metres up (raises the eye height while walking on the terrain).
    pub up: f32,
    /// Degrees to turn clockwise.
    pub yaw: f32,
    /// Degrees to look up (clamped to −90…90).
    pub pitch: f32,
}

/// Client → server control messages (JSON text, tagged by `type`).
#[derive(Debug, Deserialize, ToSchema)]
#[serde(tag = "type", rename_all = "snake_case")]
pub enum ClientMessage {
    /// Sets camera parameters; those left out are kept. `position: [x, y]` walks on the
    /// terrain at `eye_height`, `[x, y, z]` flies.
    Camera(CameraParams),
    /// Moves the camera relative to where it is.
    Move(Move),
    /// Changes the style: `style` fields are merged into the session's overrides, a `preset`
    /// becomes the base they merge over, and `layer_styles` fields are merged into each named
    /// layer's overrides (or all of them replace the session's with `replace: true`).
    /// Answered by a `style` message with the styles the session renders now.
    Style {
        /// Style fields (README, "Style").
        #[serde(default)]
        #[schema(value_type = Object)]
        style: Box<PartialStyle>,
        /// Style preset the overrides merge over.
        #[serde(default)]
        preset: Option<String>,
        /// Per-layer partial styles: layer name → style fields (or `"preset"`).
        #[serde(default)]
        #[schema(value_type = Object)]
        layer_styles: BTreeMap<String, LayerStyle>,
        /// Replace all overrides instead of merging.
        #[serde(default)]
        replace: bool,
    },
    /// Sets the size of still frames.
    Size {
        /// Width in pixels.
        width: u32,
        /// Height in pixels.
        height: u32,
    },
    /// Sets the format and quality of still frames.
    Quality {
        /// `png` or `jpeg`.
        format: Option<String>,
        /// JPEG quality 1–100.
        quality: Option<u32>,
    },
    /// Replaces the session's data layers and time (D3–D5): `mappings` as in the render
    /// body (empty or left out: none), `time` ISO 8601 (left out: each layer's first step).
    /// Answered by a `data` message with the warnings of Table 9.1 and clamped times.
    Data {
        /// Up to 3 mappings of stored layers onto visual features.
        #[serde(default)]
        mappings: Vec<Mapping>,
        /// Time of the data layers.
        #[serde(default)]
        time: Option<String>,
    },
    /// Opens a meeting presented by this session (presenter mode): allowed when the client
    /// connected as admin (the admin guard), or with the meeting password or admin token.
    /// Answered by a `meeting` message with the join code.
    OpenMeeting {
        /// The meeting password (`--meeting-password`).
        #[serde(default)]
        password: Option<String>,
        /// The admin token (browsers cannot send it as header on a WebSocket).
        #[serde(default)]
        token: Option<String>,
        /// A caption followers see (plain text, at most 500 characters).
        #[serde(default)]
        caption: Option<String>,
    },
    /// Ends the meeting this session presents; followers get `meeting_ended`.
    CloseMeeting,
    /// The presenter sets the caption its followers see (none: `text` left out).
    Caption {
        /// Plain text, at most 500 characters.
        #[serde(default)]
        text: Option<String>,
    },
    /// Follows the meeting with join code `code`: the session shows the presenter's frames.
    Join {
        /// The join code (case and a dash do not matter).
        code: String,
    },
    /// A follower goes on on its own, from the presenter's camera and style.
    Detach,
    /// Follows again the meeting the session detached from.
    Rejoin,
    /// Plays, steps through or stops a tour of viewpoints.
    Tour(TourControl),
    /// Before / after: shows the view without the vegetation layer `layer` (the plan), or
    /// with `split` (0…1 of the width) without it left of the split and with it right of it;
    /// `layer` left out (or null) ends the comparison. Answered by a `compare` message.
    Compare {
        /// The compared layer; none: no comparison.
        #[serde(default)]
        layer: Option<String>,
        /// The split position, 0…1 of the image width from the left.
        #[serde(default)]
        split: Option<f32>,
    },
    /// Shows (`show: true`) or hides the visible comments as numbered pins in the view; the
    /// pins follow new, hidden and removed comments.
    Comments {
        /// Whether to draw the pins.
        show: bool,
    },
    /// Asks for a `pong` with the same `id`.
    Ping {
        /// Any JSON value, echoed.
        #[serde(default)]
        #[schema(value_type = Object)]
        id: Value,
    },
}

/// Server → client JSON messages (tagged by `type`).
#[derive(Debug, Serialize, ToSchema)]
#[serde(tag = "type", rename_all = "snake_case")]
pub enum ServerMessage {
    /// Sent once after connecting.
    Hello {
        /// Session number.
        session: u64,
        /// Protocol and frame-header version.
        protocol: u8,
        /// Scene name.
        scene: String,
        /// The session's camera.
        camera: CameraInfo,
        /// Still-frame width.
        width: u32,
        /// Still-frame height.
        height: u32,
        /// Still-frame format.
        format: ImageFormat,
        /// Milliseconds of rest before a still frame.
        still_delay_ms: u64,
        /// Seconds without a client message before the server closes the session.
        idle_timeout_s: u64,
    },
    /// Describes the binary frame that follows it.
    Frame {
        /// Frame number (1, 2, …).
        id: u32,
        /// Control messages applied when the frame's view was taken.
        seq: u32,
        /// A full-quality still (else an interactive frame).
        still: bool,
        /// Image width.
        width: u32,
        /// Image height.
        height: u32,
        /// Image format.
        format: ImageFormat,
        /// Renderer milliseconds.
        render_ms: f32,
        /// The camera of the frame.
        camera: CameraInfo,
    },
    /// Answer to a `style` control: the complete styles the session renders from now on, as
    /// the server resolved them (presets, overrides and layer styles merged).
    Style {
        /// The view's style.
        #[schema(value_type = Object)]
        style: Style,
        /// The styles of the layers that have their own, by layer name.
        #[schema(value_type = Object)]
        layer_styles: BTreeMap<String, Style>,
    },
    /// Answer to a `data` control: the normalized time and the warnings.
    Data {
        /// The time as RFC 3339, if one was given.
        time: Option<String>,
        /// Unsuitable or limited mappings (Table 9.1) and clamped times.
        warnings: Vec<String>,
    },
    /// The art maps changed (`/api/artmaps`): how many there are now; a frame of the view
    /// with the new maps follows.
    ArtMaps {
        /// Tonal art maps (`hatch_map` 0…tams − 1).
        tams: usize,
        /// Silhouette art maps (`silhouette_map` 0…sams − 1).
        sams: usize,
    },
    /// The session's meeting: sent on opening, joining, detaching, and when the caption or
    /// the number of followers changes.
    Meeting {
        /// The join code.
        code: String,
        /// `presenter`, `follower` or `detached`.
        role: MeetingRole,
        /// The presenter's caption.
        caption: Option<String>,
        /// Sessions following.
        followers: usize,
        /// The page followers open: `/?meeting=CODE`.
        join_url: String,
        /// The join link as QR code (SVG).
        qr_url: String,
    },
    /// The meeting ended (closed by its presenter, the presenter left, or an administrator);
    /// a follower goes on on its own from the presenter's last view.
    MeetingEnded {
        /// The join code.
        code: String,
        /// Why, in words.
        reason: String,
    },
    /// A tour's progress: the camera flies to, or arrived at, viewpoint `index`, or the tour
    /// finished or stopped.
    Tour {
        /// `flying`, `arrived`, `finished` or `stopped`.
        event: TourEvent,
        /// The viewpoint (0-based).
        index: usize,
        /// Viewpoints in the tour.
        count: usize,
        /// The viewpoint's name.
        name: Option<String>,
        /// The viewpoint's caption.
        caption: Option<String>,
    },
    /// Comments, layers, viewpoints or art maps changed (`what`); see the guide's
    /// "Participation" chapter.
    Changed(Changed),
    /// Answer to a `compare` control: the comparison the session renders now.
    Compare {
        /// The compared layer (null: none).
        layer: Option<String>,
        /// The split position (null: the layer hidden in the whole view).
        split: Option<f32>,
    },
    /// Answer to `ping`.
    Pong {
        /// The ping's `id`.
        #[schema(value_type = Object)]
        id: Value,
    },
    /// A control message was rejected (the session goes on unchanged) or a render failed.
    Error(ErrorDetail),
}

/// The 20-byte header of a binary frame (all integers little-endian).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FrameHeader {
    /// Image format.
    pub format: ImageFormat,
    /// Frame number.
    pub frame_id: u32,
    /// Control messages applied when the frame's view was taken.
    pub seq: u32,
    /// Image width.
    pub width: u16,
    /// Image height.
    pub height: u16,
    /// Renderer milliseconds (saturating).
    pub render_ms: u16,
    /// Still (true) or interactive frame.
    pub still: bool,
    /// JPEG quality, 0 for PNG.
    pub quality: u8,
}

impl FrameHeader {
    /// Writes the header: magic `LS`, version, format (0 PNG, 1 JPEG), frame id u32, control
    /// seq u32, width u16, height u16, render ms u16, kind u8 (0 interactive, 1 still),
    /// quality u8.
    pub fn encode(&self) -> [u8; HEADER_LEN] {
        let mut h = [0u8; HEADER_LEN];
        h[0..2].copy_from_slice(&MAGIC);
        h[2] = PROTOCOL_VERSION;
        h[3] = match self.format {
            ImageFormat::Png => 0,
            ImageFormat::Jpeg => 1,
        };
        h[4..8].copy_from_slice(&self.frame_id.to_le_bytes());
        h[8..12].copy_from_slice(&self.seq.to_le_bytes());
        h[12..14].copy_from_slice(&self.width.to_le_bytes());
        h[14..16].copy_from_slice(&self.height.to_le_bytes());
        h[16..18].copy_from_slice(&self.render_ms.to_le_bytes());
        h[18] = u8::from(self.still);
        h[19] = self.quality;
        h
    }

    /// Reads a header from the start of a binary frame; `None` when it is not one.
    pub fn decode(bytes: &[u8]) -> Option<FrameHeader> {
        let h: &[u8; HEADER_LEN] = bytes.get(..HEADER_LEN)?.try_into().ok()?;
        if h[0..2] != MAGIC || h[2] != PROTOCOL_VERSION {
            return None;
        }
        let u16_at = |i: usize| u16::from_le_bytes([h[i], h[i + 1]]);
        let u32_at = |i: usize| u32::from_le_bytes([h[i], h[i + 1], h[i + 2], h[i + 3]]);
        Some(FrameHeader {
            format: match h[3] {
                0 => ImageFormat::Png,
                1 => ImageFormat::Jpeg,
                _ => return None,
            },
            frame_id: u32_at(4),
            seq: u32_at(8),
            width: u16_at(12),
            height: u16_at(14),
            render_ms: u16_at(16),
            still: h[18] == 1,
            quality: h[19],
        })
    }
}

/// Opens a WebSocket session. The query takes the parameters of `GET /api/render` for the
/// initial view (e.g. `?width=800&height=600&format=jpeg`), and `meeting=CODE` to follow a
/// meeting from the start.
#[utoipa::path(get, path = "/api/ws", tag = "render", params(RenderQuery),
    responses(
        (status = 101, description = "WebSocket session: JSON `ClientMessage`s in, JSON `ServerMessage`s and binary frames out (README, \"WebSocket\")"),
        (status = 400, description = "Not a WebSocket upgrade or malformed parameter", body = super::error::ErrorBody),
        (status = 404, description = "No open meeting has the `meeting` code", body = super::error::ErrorBody),
        (status = 413, description = "Initial image too large", body = super::error::ErrorBody),
        (status = 422, description = "Initial view out of range", body = super::error::ErrorBody),
        (status = 503, description = "Too many sessions, or the scene is loading", body = super::error::ErrorBody)))]
pub async fn upgrade(
    State(state): State<AppState>,
    admin: Result<Admin, ApiError>,
    RawQuery(query): RawQuery,
    ws: Result<WebSocketUpgrade, axum::extract::ws::rejection::WebSocketUpgradeRejection>,
) -> Result<Response, ApiError> {
    let ws = ws.map_err(|e| ApiError::BadRequest { parameter: None, message: e.body_text() })?;
    let ready = state.ready().ok_or(ApiError::NotReady)?;
    let (code, query) = super::meetings::split_query(query.as_deref().unwrap_or_default());
    let join = match code {
        Some(code) => Some(super::replicas::find_meeting(&state, &code).await?),
        None => None,
    };
    let params = ViewParams::from_query(&query)?;
    let initial = params.normalize(&ready.scene, state.store(), state.limits(), Source::Query)?;
    let walking = !matches!(params.camera.position.as_deref(), Some([_, _, _]));
    let config = state.config();
    let slot = Slot::take(&state, join.is_some())?;
    state.metrics().sessions_opened.inc();
    let ws = ws.max_message_size(config.ws_max_message).max_frame_size(config.ws_max_message);
    Ok(ws.on_upgrade(move |socket| async move {
        let Some(ready) = state.ready() else { return };
        let mut session = Session::new(&state, ready, initial, walking, admin.is_ok(), slot);
        if let Some(meeting) = join {
            session.follow(&meeting);
        }
        tracing::info!(session = session.id, "WebSocket session opened");
        let id = session.id;
        session.run(socket).await;
        tracing::info!(session = id, "WebSocket session closed");
    }))
}

/// What a session holds of the server's capacity: a rendering slot (`--max-sessions`) while it
/// renders its own view, a follower's place (`--max-followers`) while it shows a meeting's
/// frames, which cost no render. Counted in the `sessions` or `followers` gauge while held.
enum Slot {
    Rendering(Metrics),
    Following(Metrics),
}

impl Slot {
    /// Takes a slot of the kind asked for; `Busy` when all are held.
    fn take(state: &AppState, following: bool) -> Result<Slot, ApiError> {
        let (metrics, config) = (state.metrics(), state.config());
        let (gauge, limit) = if following {
            (&metrics.followers, config.max_followers)
        } else {
            (&metrics.sessions, config.max_sessions)
        };
        let before = gauge.inc();
        if usize::try_from(before).unwrap_or(usize::MAX) >= limit {
            gauge.dec();
            let message = if following {
                format!("this server lets at most {limit} WebSocket sessions follow meetings")
            } else {
                format!("this server takes at most {limit} WebSocket sessions that render their own view")
            };
            return Err(ApiError::Busy { message, retry_after: 5 });
        }
        let metrics = metrics.clone();
        Ok(if following { Slot::Following(metrics) } else { Slot::Rendering(metrics) })
    }

    fn is_following(&self) -> bool {
        matches!(self, Slot::Following(_))
    }
}

impl Drop for Slot {
    fn drop(&mut self) {
        match self {
            Slot::Rendering(m) => m.sessions.dec(),
            Slot::Following(m) => m.followers.dec(),
        };
    }
}

/// What the session shows: the state that control messages change.
struct View {
    camera: Camera,
    /// Eye height above the terrain while walking; `None` while flying.
    eye_height: Option<f32>,
    /// The styles as the control messages gave them (merged) and as resolved.
    requested: ViewStyle,
    styles: FrameStyle,
    width: u32,
    height: u32,
    format: ImageFormat,
    quality: u8,
    data: DataRequest,
    compare: Option<Compare>,
    /// The comment pins when the session shows comments.
    comments: Option<Vec<Pin>>,
    /// The pins are to be read again from the store (comments shown, or changed).
    pins_stale: bool,
}

struct InFlight {
    view: ViewRequest,
    kind: FrameKind,
    seq: u32,
    /// The art-map generation when the view was queued.
    art: u64,
    receiver: FrameReceiver,
}

enum Event {
    Message(Option<Result<Message, axum::Error>>),
    Frame(Result<Frame, PoolError>),
    Meeting(meeting::MeetingEvent),
    Present(Presenter),
    ArtMaps,
    Live(Result<Changed, u64>),
    Wake,
    Idle,
    Shutdown,
}

struct Session<'a> {
    id: u64,
    state: &'a AppState,
    ready: &'a Ready,
    lane: SessionLane,
    view: View,
    /// Control messages applied so far.
    seq: u32,
    frame_id: u32,
    last_control: Option<Instant>,
    last_submit: Option<Instant>,
    last_message: Instant,
    delivered: Option<ViewRequest>,
    in_flight: Option<InFlight>,
    wake_at: Option<Instant>,
    /// Whether the admin guard admitted the client when it connected (it may open meetings).
    admitted: bool,
    /// The session's part in a meeting.
    meeting: Option<meeting::Role>,
    /// Where a meeting opened for this session over REST arrives.
    mailbox: Mailbox,
    /// The tour being played.
    tour: Option<tour::TourPlay>,
    /// The capacity the session holds: rendering or following.
    slot: Slot,
}

impl<'a> Session<'a> {
    fn new(
        state: &'a AppState,
        ready: &'a Ready,
        initial: ViewRequest,
        walking: bool,
        admitted: bool,
        slot: Slot,
    ) -> Session<'a> {
        let lane = ready.pool.session_lane();
        let camera = initial.camera;
        let ground = |c: &Camera| ready.scene.terrain.height_at(f64::from(c.position[0]), f64::from(c.position[1]));
        let eye_height = if walking { ground(&camera).map(|g| camera.position[2] - g as f32) } else { None };
        Session {
            id: lane.id(),
            mailbox: state.meetings().register(lane.id()),
            admitted,
            meeting: None,
            tour: None,
            slot,
            state,
            ready,
            lane,
            view: View {
                camera,
                eye_height,
                requested: ViewStyle::of_frame(&initial.frame_style()),
                styles: initial.frame_style(),
                width: initial.width,
                height: initial.height,
                format: initial.format,
                quality: initial.quality.unwrap_or(DEFAULT_JPEG_QUALITY),
                data: initial.data,
                compare: initial.compare,
                pins_stale: initial.comments.is_some(),
                comments: initial.comments,
            },
            seq: 0,
            frame_id: 0,
            last_control: None,
            last_submit: None,
            last_message: Instant::now(),
            delivered: None,
            in_flight: None,
            wake_at: None,
        }
    }

    async fn run(mut self, socket: WebSocket) {
        let config = self.state.config();
        let mut shutdown = self.state.shutdown_receiver();
        let mut socket = Link { socket, send_timeout: config.ws_send_timeout(), shutdown: shutdown.clone() };
        let mut art_maps = self.ready.art.subscribe();
        let mut live = self.state.events().subscribe();
        let hello = ServerMessage::Hello {
            session: self.id,
            protocol: PROTOCOL_VERSION,
            scene: self.ready.scene.name.clone(),
            camera: CameraInfo::from(&self.view.camera),
            width: self.view.width,
            height: self.view.height,
            format: self.view.format,
            still_delay_ms: config.still_delay_ms,
            idle_timeout_s: config.idle_timeout_s,
        };
        if let Err(failed) = socket.send_json(&hello).await {
            return self.ended(failed);
        }
        if let Some(message) = self.meeting_message()
            && let Err(failed) = socket.send_json(&message).await
        {
            return self.ended(failed);
        }
        self.refresh_pins().await;
        self.schedule(Instant::now());
        loop {
            let idle_at = self.last_message + config.idle_timeout();
            let wake_at = self.wake_at;
            let event = tokio::select! {
                message = socket.socket.recv() => Event::Message(message),
                frame = frame_done(&mut self.in_flight) => Event::Frame(frame),
                event = meeting::next_event(&mut self.meeting) => Event::Meeting(event),
                Some(presenter) = self.mailbox.recv() => Event::Present(presenter),
                Ok(()) = art_maps.changed() => Event::ArtMaps,
                event = next_live(&mut live) => Event::Live(event),
                () = sleep_until(wake_at) => Event::Wake,
                () = tokio::time::sleep_until(idle_at) => Event::Idle,
                _ = shutdown.wait_for(|stopping| *stopping) => Event::Shutdown,
            };
            let now = Instant::now();
            let outgoing = match event {
                Event::Message(Some(Ok(message))) => {
                    self.last_message = now;
                    match message {
                        Message::Text(text) => self.handle_text(text.as_str(), now).await,
                        Message::Binary(_) => Some(self.reject(ApiError::BadRequest {
                            parameter: None,
                            message: "binary messages are not accepted; send JSON text".into(),
                        })),
                        Message::Close(_) => return,
                        Message::Ping(_) | Message::Pong(_) => None,
                    }
                }
                Event::Message(Some(Err(error))) => {
                    if is_too_long(error) {
                        socket.close(close_code::SIZE, "message too big").await;
                        // The rest of the message is unread: closing now would reset the
                        // connection and could discard the close frame before the client reads it.
                        tokio::time::sleep(CLOSE_LINGER).await;
                    }
                    return;
                }
                Event::Message(None) => return,
                Event::Frame(result) => {
                    if let Err(failed) = self.deliver(&mut socket, result).await {
                        return self.ended(failed);
                    }
                    None
                }
                Event::Meeting(event) => match self.on_meeting_event(&mut socket, event).await {
                    Ok(message) => message,
                    Err(failed) => return self.ended(failed),
                },
                Event::Present(presenter) => Some(match self.take_slot(false) {
                    Ok(()) => self.start_presenting(presenter),
                    Err(e) => {
                        presenter.close("the presenter's session could not get a rendering slot");
                        self.reject(e)
                    }
                }),
                Event::ArtMaps => {
                    // The view is shown again with the new maps.
                    self.delivered = None;
                    let (tams, sams) = self.ready.art.counts();
                    Some(ServerMessage::ArtMaps { tams, sams })
                }
                Event::Live(Ok(event)) => {
                    self.view.pins_stale |= self.view.comments.is_some() && matches!(event, Changed::Comments { .. });
                    Some(ServerMessage::Changed(event))
                }
                Event::Live(Err(missed)) => {
                    tracing::debug!(session = self.id, missed, "session fell behind the live events");
                    self.view.pins_stale |= self.view.comments.is_some();
                    for reload in super::events::reload_all() {
                        if let Err(failed) = socket.send_json(&ServerMessage::Changed(reload)).await {
                            return self.ended(failed);
                        }
                    }
                    None
                }
                Event::Wake => None,
                Event::Idle => {
                    socket.close(close_code::AWAY, "idle timeout").await;
                    return;
                }
                Event::Shutdown => {
                    socket.close(close_code::AWAY, "server shutting down").await;
                    return;
                }
            };
            let tour = self.advance_tour(now, config.frame_interval());
            for message in outgoing.into_iter().chain(tour) {
                if let Err(failed) = socket.send_json(&message).await {
                    return self.ended(failed);
                }
            }
            self.refresh_pins().await;
            self.schedule(now);
            if let Some(wake) = self.tour.as_ref().and_then(|t| t.wake) {
                self.wake_at = Some(self.wake_at.map_or(wake, |w| w.min(wake)));
            }
        }
    }

    /// Makes the session hold a rendering slot (`following` false) or a follower's place;
    /// the other is given back. `Busy` (and nothing changes) when none is free.
    fn take_slot(&mut self, following: bool) -> Result<(), ApiError> {
        if self.slot.is_following() != following {
            self.slot = Slot::take(self.state, following)?;
        }
        Ok(())
    }

    /// Logs why a send ended the session (a client that does not read is worth a warning).
    fn ended(&self, failed: SendFailed) {
        match failed {
            SendFailed::NoSlot => {
                tracing::info!(session = self.id, "meeting ended with every rendering slot taken; follower closed");
            }
            SendFailed::Deadline => {
                tracing::warn!(session = self.id, "client took no message within --ws-send-timeout-s; closed");
            }
            SendFailed::Closed | SendFailed::ShuttingDown => {
                tracing::debug!(session = self.id, ?failed, "session ended while sending");
            }
        }
    }

    /// Applies one control message; returns the message to answer with, if any.
    async fn handle_text(&mut self, text: &str, now: Instant) -> Option<ServerMessage> {
        let message = match serde_json::from_str::<ClientMessage>(text) {
            Ok(message) => message,
            Err(e) => {
                return Some(self.reject(ApiError::BadRequest {
                    parameter: None,
                    message: format!("unreadable control message: {e}"),
                }));
            }
        };
        let interaction = matches!(
            message,
            ClientMessage::Camera(_)
                | ClientMessage::Move(_)
                | ClientMessage::Style { .. }
                | ClientMessage::Data { .. }
        );
        let mut answer = None;
        if matches!(
            message,
            ClientMessage::Camera(_)
                | ClientMessage::Move(_)
                | ClientMessage::Style { .. }
                | ClientMessage::Data { .. }
                | ClientMessage::Tour(_)
                | ClientMessage::OpenMeeting { .. }
        ) && let Err(error) = self.refuse_while_following()
        {
            return Some(self.reject(error));
        }
        if matches!(message, ClientMessage::Camera(_) | ClientMessage::Move(_)) {
            // A camera control takes over from a tour.
            answer = self.stop_tour();
        }
        let mut reply = |message: Result<ServerMessage, ApiError>| message.map(|m| answer = Some(m));
        let applied = match message {
            ClientMessage::Ping { id } => return Some(ServerMessage::Pong { id }),
            ClientMessage::OpenMeeting { password, token, caption } => {
                reply(self.open_meeting(password, token, caption))
            }
            ClientMessage::CloseMeeting => reply(self.close_meeting()),
            ClientMessage::Caption { text } => reply(self.set_meeting_caption(text)),
            ClientMessage::Join { code } => reply(self.join(&code).await),
            ClientMessage::Detach => reply(self.detach()),
            ClientMessage::Rejoin => reply(self.rejoin()),
            ClientMessage::Tour(control) => reply(self.tour_control(control, now).await),
            ClientMessage::Data { mappings, time } => {
                DataRequest::resolve(&mappings, time.as_deref(), self.state.store()).map_err(ApiError::from).map(
                    |data| {
                        answer = Some(ServerMessage::Data { time: data.time.clone(), warnings: data.warnings.clone() });
                        self.view.data = data;
                    },
                )
            }
            ClientMessage::Camera(params) => self.set_camera(&params),
            ClientMessage::Move(m) => self.move_camera(&m),
            ClientMessage::Style { style, preset, layer_styles, replace } => {
                self.set_style(&ViewStyle { preset, style: *style, layer_styles }, replace).map(|styles| {
                    answer =
                        Some(ServerMessage::Style { style: styles.base.clone(), layer_styles: styles.layers.clone() });
                })
            }
            ClientMessage::Compare { layer, split } => self.set_compare(layer, split).map(|()| {
                let compare = self.view.compare.as_ref();
                answer = Some(ServerMessage::Compare {
                    layer: compare.map(|c| c.layer.clone()),
                    split: compare.and_then(|c| c.split),
                });
            }),
            ClientMessage::Comments { show } => {
                self.view.comments = show.then(|| self.view.comments.take().unwrap_or_default());
                self.view.pins_stale = show;
                Ok(())
            }
            ClientMessage::Size { width, height } => self.set_size(width, height),
            ClientMessage::Quality { format, quality } => self.set_quality(format.as_deref(), quality),
        };
        match applied {
            Ok(()) => {
                self.seq += 1;
                if interaction {
                    self.last_control = Some(now);
                }
                answer
            }
            Err(error) => Some(self.reject(error)),
        }
    }

    /// Reads the comment pins again when they are stale; a store failure keeps the old ones
    /// (and is logged), so the view goes on.
    async fn refresh_pins(&mut self) {
        if !std::mem::take(&mut self.view.pins_stale) || self.view.comments.is_none() {
            return;
        }
        match super::comments::comment_pins(self.state, self.ready).await {
            Ok(pins) => self.view.comments = Some(pins),
            Err(error) => tracing::warn!(session = self.id, %error, "cannot read the comments for the pins"),
        }
    }

    fn reject(&self, error: ApiError) -> ServerMessage {
        self.state.metrics().ws_bad_messages.inc();
        ServerMessage::Error(error.detail())
    }

    fn set_camera(&mut self, params: &CameraParams) -> Result<(), ApiError> {
        let mut params = params.clone();
        if let Some([x, y, z]) = params.position.as_deref().and_then(|p| <[f32; 3]>::try_from(p).ok()) {
            params.position = Some(vec![x, y, self.flying_z([x, y, z])]);
        }
        let resolved = params.resolve(&self.view.camera, &self.ready.scene, Source::Message)?;
        if params.position.is_some() || params.eye_height.is_some() {
            self.view.eye_height = resolved.eye_height;
        }
        self.view.camera = resolved.camera;
        Ok(())
    }

    /// The elevation of a flying eye asked for at `[x, y, z]`: flying down onto the ground (or
    /// into a hill) lands the eye eye height above it, as a walker's; under the ground a frame
    /// would show nothing but paper.
    fn flying_z(&self, [x, y, z]: [f32; 3]) -> f32 {
        let terrain = &self.ready.scene.terrain;
        terrain.buries([x, y, z - DEFAULT_EYE_HEIGHT]).map_or(z, |ground| ground as f32 + DEFAULT_EYE_HEIGHT)
    }

    fn move_camera(&mut self, m: &Move) -> Result<(), ApiError> {
        for (name, value, limit) in [
            ("forward", m.forward, 10_000.0),
            ("right", m.right, 10_000.0),
            ("up", m.up, 10_000.0),
            ("yaw", m.yaw, 3600.0),
            ("pitch", m.pitch, 180.0),
        ] {
            if !(value.is_finite() && value.abs() <= limit) {
                return Err(ApiError::invalid(name, format!("{name} {value} is outside ±{limit}")));
            }
        }
        let mut camera = self.view.camera;
        camera.yaw = (camera.yaw + m.yaw).rem_euclid(360.0);
        camera.pitch = (camera.pitch + m.pitch).clamp(-90.0, 90.0);
        let (sin, cos) = camera.yaw.to_radians().sin_cos();
        let [x, y, z] = camera.position;
        let (x, y) = (x + m.forward * sin + m.right * cos, y + m.forward * cos - m.right * sin);
        let (z, eye_height) = match self.view.eye_height {
            Some(eye) => {
                let eye = (eye + m.up).max(0.1);
                let ground = self.ready.scene.terrain.height_at(f64::from(x), f64::from(y)).ok_or_else(|| {
                    ApiError::invalid("forward", format!("the move to {x:.1},{y:.1} leaves the terrain"))
                })?;
                (ground as f32 + eye, Some(eye))
            }
            None => (self.flying_z([x, y, z + m.up]), None),
        };
        camera.position = [x, y, z];
        self.view.camera = camera;
        self.view.eye_height = eye_height;
        Ok(())
    }

    /// Merges a `style` control into the session's styles (or replaces them) and resolves
    /// them; returns what the session renders now.
    fn set_style(&mut self, change: &ViewStyle, replace: bool) -> Result<&FrameStyle, ApiError> {
        let mut requested = if replace { ViewStyle::default() } else { self.view.requested.clone() };
        requested.merge(change);
        self.view.styles = requested.resolve(&self.ready.scene.layer_names())?;
        self.view.requested = requested;
        Ok(&self.view.styles)
    }

    fn set_compare(&mut self, layer: Option<String>, split: Option<f32>) -> Result<(), ApiError> {
        let compare = match (layer, split) {
            (Some(layer), split) => Some(Compare { layer, split }),
            (None, None) => None,
            (None, Some(_)) => return Err(ApiError::invalid("split", "split needs layer: the layer to compare")),
        };
        if let Some(compare) = &compare {
            check_compare(compare, &self.ready.scene.layer_names())?;
        }
        self.view.compare = compare;
        Ok(())
    }

    fn set_size(&mut self, width: u32, height: u32) -> Result<(), ApiError> {
        let config = self.state.config();
        let width = image_side("width", width, config.max_width)?;
        let height = image_side("height", height, config.max_height)?;
        (self.view.width, self.view.height) = (width, height);
        Ok(())
    }

    fn set_quality(&mut self, format: Option<&str>, quality: Option<u32>) -> Result<(), ApiError> {
        let format = format.map(|f| image_format(f, "format")).transpose()?.unwrap_or(self.view.format);
        let quality = match quality {
            Some(q) => jpeg_quality(Some(q), "quality")?,
            None => self.view.quality,
        };
        (self.view.format, self.view.quality) = (format, quality);
        Ok(())
    }

    /// The view to show now: interactive while controls keep coming, else the still.
    fn target(&self, now: Instant) -> (ViewRequest, FrameKind) {
        let config = self.state.config();
        let v = &self.view;
        let moving = self.last_control.is_some_and(|t| now < t + config.still_delay());
        let (width, height, format, quality, kind) = if moving {
            let scale = |side: u32| ((side as f32 * config.interactive_scale).round() as u32).max(1);
            (scale(v.width), scale(v.height), ImageFormat::Jpeg, config.interactive_quality, FrameKind::Interactive)
        } else {
            (v.width, v.height, v.format, v.quality, FrameKind::Still)
        };
        let quality = (format == ImageFormat::Jpeg).then_some(quality);
        (
            ViewRequest {
                camera: v.camera,
                width,
                height,
                format,
                quality,
                style: v.styles.base.clone(),
                layer_styles: v.styles.layers.clone(),
                data: v.data.clone(),
                compare: v.compare.clone(),
                comments: v.comments.clone(),
            },
            kind,
        )
    }

    /// Queues the view to show if it is not shown or coming already; sets the next wake-up
    /// (the still after rest, or the next paced interactive frame).
    fn schedule(&mut self, now: Instant) {
        if self.is_following() {
            // A follower renders nothing and needs no wake-up.
            self.wake_at = None;
            return;
        }
        let config = self.state.config();
        let (view, kind) = self.target(now);
        self.wake_at = self.last_control.map(|t| t + config.still_delay()).filter(|t| *t > now);
        if let Some(in_flight) = &mut self.in_flight {
            if in_flight.view == view {
                in_flight.seq = self.seq;
            } else if let Some(receiver) = self.lane.replace(view.clone(), kind) {
                *in_flight = InFlight { view, kind, seq: self.seq, art: self.ready.art.generation(), receiver };
            }
            // Otherwise the render has started; the newest view follows when it is done.
            return;
        }
        if self.delivered.as_ref() == Some(&view) {
            return;
        }
        if kind == FrameKind::Interactive
            && let Some(paced) = self.last_submit.map(|t| t + config.frame_interval()).filter(|t| *t > now)
        {
            self.wake_at = Some(self.wake_at.map_or(paced, |w| w.min(paced)));
            return;
        }
        match self.lane.render(view.clone(), kind) {
            Ok(receiver) => {
                let art = self.ready.art.generation();
                self.in_flight = Some(InFlight { view, kind, seq: self.seq, art, receiver });
                self.last_submit = Some(now);
            }
            Err(error) => tracing::debug!(session = self.id, %error, "no render queued"),
        }
    }

    /// Sends a finished frame (a `frame` message, then the binary frame) or its error.
    async fn deliver(&mut self, socket: &mut Link, result: Result<Frame, PoolError>) -> Result<(), SendFailed> {
        let Some(done) = self.in_flight.take() else { return Ok(()) };
        let frame = match result {
            Ok(frame) => frame,
            Err(PoolError::Cancelled) => return Ok(()),
            Err(error) => {
                // Do not retry the same view in a loop: it counts as delivered.
                self.delivered = Some(done.view);
                return socket.send_json(&ServerMessage::Error(pool_error(error).detail())).await;
            }
        };
        self.frame_id += 1;
        let view = &done.view;
        let (text, binary) = encode_frame(self.frame_id, done.seq, done.kind == FrameKind::Still, view, &frame)
            .ok_or(SendFailed::Closed)?;
        self.publish(&text, &binary, view);
        socket.send(Message::Text(text)).await?;
        socket.send(Message::Binary(binary)).await?;
        self.state.metrics().frames_sent.get_or_create(&done.kind.label()).inc();
        // A frame queued before an art-map change may show the old maps: it is shown again.
        self.delivered = (done.art == self.ready.art.generation()).then_some(done.view);
        Ok(())
    }
}

/// The `frame` message and the binary frame (header and image) of `frame`, a render of
/// `view`, as frame `frame_id` answering control `seq`; `None` if the message cannot be
/// encoded.
pub(crate) fn encode_frame(
    frame_id: u32,
    seq: u32,
    still: bool,
    view: &ViewRequest,
    frame: &Frame,
) -> Option<(Utf8Bytes, Bytes)> {
    let status = ServerMessage::Frame {
        id: frame_id,
        seq,
        still,
        width: view.width,
        height: view.height,
        format: view.format,
        render_ms: frame.render_ms,
        camera: CameraInfo::from(&view.camera),
    };
    let header = FrameHeader {
        format: view.format,
        frame_id,
        seq,
        width: u16::try_from(view.width).unwrap_or(u16::MAX),
        height: u16::try_from(view.height).unwrap_or(u16::MAX),
        render_ms: frame.render_ms.round().clamp(0.0, f32::from(u16::MAX)) as u16,
        still,
        quality: view.quality.unwrap_or(0),
    };
    let mut binary = Vec::with_capacity(HEADER_LEN + frame.bytes.len());
    binary.extend_from_slice(&header.encode());
    binary.extend_from_slice(&frame.bytes);
    let text = Utf8Bytes::from(serde_json::to_string(&status).ok()?);
    Some((text, Bytes::from(binary)))
}

async fn frame_done(in_flight: &mut Option<InFlight>) -> Result<Frame, PoolError> {
    match in_flight {
        Some(f) => (&mut f.receiver).await.unwrap_or(Err(PoolError::Cancelled)),
        None => std::future::pending().await,
    }
}

/// The next live event; `Err(n)` when the session fell `n` events behind. The sender lives in
/// the app state, so the channel never closes while a session runs.
async fn next_live(live: &mut tokio::sync::broadcast::Receiver<Changed>) -> Result<Changed, u64> {
    use tokio::sync::broadcast::error::RecvError;
    match live.recv().await {
        Ok(event) => Ok(event),
        Err(RecvError::Lagged(missed)) => Err(missed),
        Err(RecvError::Closed) => std::future::pending().await,
    }
}

async fn sleep_until(deadline: Option<Instant>) {
    match deadline {
        Some(deadline) => tokio::time::sleep_until(deadline).await,
        None => std::future::pending().await,
    }
}

/// Whether a receive error is a message or frame longer than `--ws-max-message`.
fn is_too_long(error: axum::Error) -> bool {
    matches!(error.into_inner().downcast::<tungstenite::Error>().map(|e| *e), Ok(tungstenite::Error::Capacity(_)))
}

/// Why a message was not sent; the session ends either way.
#[derive(Debug)]
enum SendFailed {
    /// The connection failed or was closed.
    Closed,
    /// The client did not take the message within `--ws-send-timeout-s`: it does not read.
    Deadline,
    /// The server is shutting down; the message was abandoned.
    ShuttingDown,
    /// A follower's meeting ended while every rendering slot was taken: it was told so and
    /// closed (it cannot go on on its own).
    NoSlot,
}

/// A session's connection: every send has a deadline and gives way to shutdown, so a client
/// that never reads cannot hold its session (and its `--max-sessions` slot) or delay the
/// shutdown. The outgoing queue is one message: the session sends one at a time, and the
/// renderer makes no frame while the last one is unsent (latest wins).
struct Link {
    socket: WebSocket,
    send_timeout: Duration,
    shutdown: tokio::sync::watch::Receiver<bool>,
}

impl Link {
    async fn send(&mut self, message: Message) -> Result<(), SendFailed> {
        tokio::select! {
            sent = tokio::time::timeout(self.send_timeout, self.socket.send(message)) => match sent {
                Ok(Ok(())) => Ok(()),
                Ok(Err(_)) => Err(SendFailed::Closed),
                Err(_) => Err(SendFailed::Deadline),
            },
            () = stopped(&mut self.shutdown) => Err(SendFailed::ShuttingDown),
        }
    }

    async fn send_json(&mut self, message: &ServerMessage) -> Result<(), SendFailed> {
        let text = serde_json::to_string(message).map_err(|_| SendFailed::Closed)?;
        self.send(Message::text(text)).await
    }

    /// Sends a close frame, waiting at most [`CLOSE_SEND_TIMEOUT`] (also at shutdown).
    async fn close(&mut self, code: u16, reason: &'static str) {
        let frame = Message::Close(Some(CloseFrame { code, reason: reason.into() }));
        // The client may be gone already or not read; the session ends either way.
        let _ = tokio::time::timeout(CLOSE_SEND_TIMEOUT, self.socket.send(frame)).await;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frame_header_round_trips_and_rejects_other_bytes() {
        let header = FrameHeader {
            format: ImageFormat::Jpeg,
            frame_id: 7,
            seq: 0x0102_0304,
            width: 1024,
            height: 768,
            render_ms: 512,
            still: true,
            quality: 90,
        };
        let bytes = header.encode();
        assert_eq!(&bytes[..4], b"LS\x01\x01");
        assert_eq!(&bytes[8..12], &[4, 3, 2, 1]);
        assert_eq!(FrameHeader::decode(&bytes), Some(header));
        assert_eq!(FrameHeader::decode(&bytes[..HEADER_LEN - 1]), None);
        assert_eq!(FrameHeader::decode(b"PNG\x0d\x0a\x1a\x0a................"), None);
    }

    #[test]
    fn control_messages_parse_and_garbage_does_not() {
        let moved: ClientMessage = serde_json::from_str(r#"{"type": "move", "yaw": 5}"#).expect("move");
        assert!(matches!(moved, ClientMessage::Move(Move { yaw: 5.0, forward: 0.0, .. })));
        let camera: ClientMessage =
            serde_json::from_str(r#"{"type": "camera", "position": [1, 2], "pitch": -3}"#).expect("camera");
        assert!(matches!(camera, ClientMessage::Camera(CameraParams { pitch: Some(-3.0), .. })));
        let data: ClientMessage = serde_json::from_str(
            r#"{"type": "data", "mappings": [{"layer": "plume", "target": "color"}], "time": "2024-07-01"}"#,
        )
        .expect("data");
        assert!(matches!(data, ClientMessage::Data { ref mappings, time: Some(_) } if mappings.len() == 1));
        let plan: ClientMessage =
            serde_json::from_str(r#"{"type": "camera", "mode": "plan", "center": [0, 0], "width": 900}"#)
                .expect("plan");
        assert!(matches!(plan, ClientMessage::Camera(CameraParams { width: Some(900.0), .. })));
        for garbage in [
            r#"{"type": "move", "speed": 1}"#,
            r#"{"type": "camera", "zoom": 2}"#,
            r#"{"type": "teleport"}"#,
            r#"{"yaw": 1}"#,
            "[]",
        ] {
            assert!(serde_json::from_str::<ClientMessage>(garbage).is_err(), "{garbage}");
        }
    }
}
