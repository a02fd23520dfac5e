//! Meetings (presenter mode): a WebSocket session opens a meeting and gets a short join code;
//! followers join with the code and receive the presenter's frames. Each frame is rendered
//! and encoded once, for the presenter, and its bytes are shared with every follower through
//! a [`watch`] of the latest frame: a follower that is slow to take a frame skips to the
//! newest one instead of holding up the presenter or the other followers, and each follower's
//! sends keep the session's send deadline (`--ws-send-timeout-s`).
//!
//! Meetings are recorded in the participation store (code, presenter session, opened and
//! closed times) for the record; the live state (frames, followers) is in memory only.
//!
//! REST: `POST /api/meetings` (open one for a session), `GET /api/meetings/{code}`,
//! `GET /api/meetings/{code}/qr.svg` (the join link as QR code), `DELETE /api/meetings/{code}`.

use super::AppState;
use super::auth::{Admin, secret_matches};
use super::error::{ApiError, ErrorBody};
use super::metrics::{MeetingLabels, Metrics};
use super::view::ViewRequest;
use crate::echo::echo;
use crate::store::participation::{self, ParticipationStore};
use axum::Json;
use axum::body::Bytes;
use axum::extract::rejection::BytesRejection;
use axum::extract::ws::Utf8Bytes;
use axum::extract::{Path, State};
use axum::http::{HeaderMap, StatusCode, header};
use axum::response::{IntoResponse, Response};
use serde::{Deserialize, Serialize};
use std::collections::HashMap;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};
use tokio::sync::{mpsc, watch};
use utoipa::ToSchema;

/// The symbols of join codes: digits and capitals without the look-alikes 0/O and 1/I/L.
pub const CODE_ALPHABET: &[u8; 31] = b"23456789ABCDEFGHJKMNPQRSTUVWXYZ";
/// Symbols in a join code (31⁶ ≈ 887 million codes).
pub const CODE_LEN: usize = 6;
/// Longest meeting caption, in characters.
pub const MAX_CAPTION: usize = 500;

/// The presenter "session" of a meeting presented on another replica and relayed here
/// (session numbers start at 1).
pub const RELAYED: u64 = 0;

/// A new random join code from the operating system's generator.
pub fn new_code() -> Result<String, ApiError> {
    let mut code = String::with_capacity(CODE_LEN);
    // Rejection sampling keeps the symbols uniform: 248 = 8 × 31.
    while code.len() < CODE_LEN {
        let mut bytes = [0u8; 16];
        getrandom::fill(&mut bytes).map_err(|e| ApiError::Internal(format!("no random numbers: {e}")))?;
        code.extend(
            bytes
                .iter()
                .filter(|b| **b < 248)
                .map(|b| char::from(CODE_ALPHABET[usize::from(*b % 31)]))
                .take(CODE_LEN - code.len()),
        );
    }
    Ok(code)
}

/// The join code a user typed, in its canonical form (upper case, no surrounding space, no
/// dash or space between the halves); `None` when it cannot be a code.
pub fn normalize_code(given: &str) -> Option<String> {
    let code: String = given.chars().filter(|c| !matches!(c, ' ' | '-')).map(|c| c.to_ascii_uppercase()).collect();
    (code.len() == CODE_LEN && code.bytes().all(|b| CODE_ALPHABET.contains(&b))).then_some(code)
}

/// Checks a caption: plain text of at most [`MAX_CAPTION`] characters, no control
/// characters; blank means none.
pub fn caption(text: Option<String>, parameter: &str) -> Result<Option<String>, ApiError> {
    let Some(text) = text else { return Ok(None) };
    let text = text.trim();
    if text.chars().count() > MAX_CAPTION {
        return Err(ApiError::invalid(parameter, format!("{parameter} is longer than {MAX_CAPTION} characters")));
    }
    if text.chars().any(|c| c.is_control() && c != '\n') {
        return Err(ApiError::invalid(parameter, format!("{parameter} holds control characters")));
    }
    Ok((!text.is_empty()).then(|| text.to_owned()))
}

/// The link followers open: the browser UI joining the meeting.
pub fn join_path(code: &str) -> String {
    format!("/?meeting={code}")
}

/// Splits the `meeting` parameter (a join code) off a WebSocket URL's query; the rest is the
/// initial view's parameters.
pub fn split_query(query: &str) -> (Option<String>, String) {
    let mut code = None;
    let mut rest = form_urlencoded::Serializer::new(String::new());
    for (key, value) in form_urlencoded::parse(query.as_bytes()) {
        if key == "meeting" {
            code = Some(value.into_owned());
        } else {
            rest.append_pair(&key, &value);
        }
    }
    (code, rest.finish())
}

/// A frame as the presenter got it: its `frame` message and binary frame, shared by every
/// follower, and the view it shows (what a follower that detaches starts from).
#[derive(Debug)]
pub struct SharedFrame {
    /// The `frame` JSON message.
    pub text: Utf8Bytes,
    /// The binary frame (header and image).
    pub binary: Bytes,
    /// The presenter's frame number.
    pub frame_id: u32,
    /// The view of the frame.
    pub view: ViewRequest,
    /// The presenter's eye height above the terrain (`None` while flying).
    pub eye_height: Option<f32>,
}

/// What followers are told about a meeting; they get a `meeting` message when it changes.
#[derive(Debug, Clone, PartialEq)]
pub struct MeetingStatus {
    /// The presenter's caption (the current tour viewpoint's, or one set with `caption`).
    pub caption: Option<String>,
    /// Sessions following now.
    pub followers: usize,
    /// Why the meeting ended, once it has.
    pub ended: Option<&'static str>,
}

/// One open meeting.
pub struct Meeting {
    /// The join code.
    pub code: String,
    /// The presenter's session number.
    pub presenter: u64,
    frames: watch::Sender<Option<Arc<SharedFrame>>>,
    status: watch::Sender<MeetingStatus>,
    renders: AtomicU64,
    metrics: Metrics,
    /// Recording the meeting in the store; closing it waits for that.
    recorded: Mutex<Option<tokio::task::JoinHandle<()>>>,
    /// Followers on other replicas (relays of this meeting), by replica.
    remote_followers: Mutex<HashMap<String, usize>>,
}

impl Meeting {
    fn labels(&self) -> MeetingLabels {
        MeetingLabels { meeting: self.code.clone() }
    }

    /// Shares a frame of the presenter with the followers (each frame counts as one render).
    pub fn publish(&self, frame: SharedFrame) {
        self.renders.fetch_add(1, Ordering::Relaxed);
        self.metrics.meeting_renders.get_or_create(&self.labels()).inc();
        self.frames.send_replace(Some(Arc::new(frame)));
    }

    /// The newest frame, if the presenter has made one since opening.
    pub fn latest(&self) -> Option<Arc<SharedFrame>> {
        self.frames.borrow().clone()
    }

    /// Sets the caption followers see.
    pub fn set_caption(&self, caption: Option<String>) {
        self.status.send_if_modified(|s| {
            let changed = s.caption != caption;
            s.caption = caption;
            changed
        });
    }

    /// The meeting's state now.
    pub fn status(&self) -> MeetingStatus {
        self.status.borrow().clone()
    }

    /// Receives the meeting's status changes (the presenter's view of its audience).
    pub fn subscribe(&self) -> watch::Receiver<MeetingStatus> {
        self.status.subscribe()
    }

    /// The presenter's frames, as they come (for relaying them to another replica; not a
    /// follower).
    pub fn watch_frames(&self) -> watch::Receiver<Option<Arc<SharedFrame>>> {
        self.frames.subscribe()
    }

    /// Adds a follower; it gets the newest frame at once, then every frame it can take.
    pub fn follow(self: &Arc<Self>) -> Follower {
        let mut frames = self.frames.subscribe();
        frames.mark_changed();
        let followers = self.change_followers(1);
        tracing::info!(meeting = %self.code, followers, "follower joined");
        Follower { meeting: self.clone(), frames, status: self.status.subscribe() }
    }

    /// Sets how many follow on another replica (`replica` relays this meeting); they count
    /// among the followers.
    pub fn set_remote_followers(&self, replica: &str, followers: usize) {
        let before = {
            let mut remote = self.remote_followers.lock().unwrap_or_else(PoisonError::into_inner);
            match followers {
                0 => remote.remove(replica),
                n => remote.insert(replica.to_owned(), n),
            }
            .unwrap_or(0)
        };
        let by = isize::try_from(followers).unwrap_or(isize::MAX) - isize::try_from(before).unwrap_or(isize::MAX);
        if by != 0 {
            self.change_followers(by);
        }
    }

    fn change_followers(&self, by: isize) -> usize {
        let mut now = 0;
        self.status.send_modify(|s| {
            s.followers = s.followers.saturating_add_signed(by);
            now = s.followers;
        });
        if self.status.borrow().ended.is_none() {
            self.metrics.meeting_followers.get_or_create(&self.labels()).set(i64::try_from(now).unwrap_or(i64::MAX));
        }
        now
    }

    /// What `GET /api/meetings/{code}` answers.
    pub fn info(&self) -> MeetingInfo {
        let status = self.status();
        MeetingInfo {
            code: self.code.clone(),
            join_url: join_path(&self.code),
            qr_url: format!("/api/meetings/{}/qr.svg", self.code),
            presenter_session: self.presenter,
            caption: status.caption,
            followers: status.followers,
            renders: self.renders.load(Ordering::Relaxed),
        }
    }
}

/// A session following a meeting: where its frames and status changes arrive. Dropping it
/// leaves the meeting.
pub struct Follower {
    /// The meeting.
    pub meeting: Arc<Meeting>,
    /// The newest frame of the presenter.
    pub frames: watch::Receiver<Option<Arc<SharedFrame>>>,
    /// The meeting's status.
    pub status: watch::Receiver<MeetingStatus>,
}

impl Drop for Follower {
    fn drop(&mut self) {
        self.meeting.change_followers(-1);
    }
}

/// The presenter's hold on its meeting: dropping it (the presenter closes the meeting or its
/// session ends) ends the meeting, and the followers are told.
pub struct Presenter {
    /// The meeting.
    pub meeting: Arc<Meeting>,
    registry: Meetings,
}

impl Presenter {
    /// Ends the meeting, telling followers `reason`.
    pub fn close(self, reason: &'static str) {
        self.registry.end(&self.meeting.code, reason);
    }
}

impl Drop for Presenter {
    fn drop(&mut self) {
        self.registry.end(&self.meeting.code, "the presenter left");
    }
}

/// Where a session receives a meeting opened for it over REST; dropping it unregisters it.
pub struct Mailbox {
    session: u64,
    receiver: mpsc::Receiver<Presenter>,
    registry: Meetings,
}

impl Mailbox {
    /// The next meeting opened for this session.
    pub async fn recv(&mut self) -> Option<Presenter> {
        self.receiver.recv().await
    }
}

impl Drop for Mailbox {
    fn drop(&mut self) {
        self.registry.lock_sessions().remove(&self.session);
    }
}

#[derive(Default)]
struct Registry {
    open: Mutex<HashMap<String, Arc<Meeting>>>,
    sessions: Mutex<HashMap<u64, mpsc::Sender<Presenter>>>,
}

/// The open meetings of a server; cheap to clone.
#[derive(Clone)]
pub struct Meetings {
    registry: Arc<Registry>,
    metrics: Metrics,
    store: Arc<dyn ParticipationStore>,
}

impl Meetings {
    /// No meetings; counts in `metrics`, records them in `store`.
    pub fn new(metrics: Metrics, store: Arc<dyn ParticipationStore>) -> Meetings {
        Meetings { registry: Arc::default(), metrics, store }
    }

    fn lock_open(&self) -> MutexGuard<'_, HashMap<String, Arc<Meeting>>> {
        self.registry.open.lock().unwrap_or_else(PoisonError::into_inner)
    }

    fn lock_sessions(&self) -> MutexGuard<'_, HashMap<u64, mpsc::Sender<Presenter>>> {
        self.registry.sessions.lock().unwrap_or_else(PoisonError::into_inner)
    }

    /// Opens a meeting presented by session `presenter` under a new code.
    pub fn open(&self, presenter: u64, caption: Option<String>) -> Result<Presenter, ApiError> {
        let mut open = self.lock_open();
        if let Some(meeting) = open.values().find(|m| m.presenter == presenter) {
            return Err(ApiError::Conflict(format!("session {presenter} presents meeting {} already", meeting.code)));
        }
        let code = loop {
            let code = new_code()?;
            if !open.contains_key(&code) {
                break code;
            }
        };
        let meeting = self.meeting(&code, presenter, caption);
        let (store, record) = (
            self.store.clone(),
            participation::Meeting {
                code: code.clone(),
                presenter: format!("session {presenter}"),
                created_ms: participation::now_ms(),
                closed_ms: None,
            },
        );
        let recording = in_background(async move {
            match store.add_meeting(record).await {
                Ok(true) => {}
                // A code is unique among open meetings; an old closed one may have had it.
                Ok(false) => tracing::warn!("a past meeting had this code; the meeting is not recorded"),
                Err(error) => tracing::error!(%error, "the meeting cannot be recorded"),
            }
        });
        *meeting.recorded.lock().unwrap_or_else(PoisonError::into_inner) = recording;
        tracing::info!(meeting = %code, session = presenter, "meeting opened");
        Ok(self.insert(&mut open, meeting))
    }

    /// Opens here the meeting `code` that a session of another replica presents (see
    /// [`super::replicas`]); its frames are the relay's. `None` when it is open here already.
    pub fn open_relay(&self, code: &str, caption: Option<String>) -> Option<Presenter> {
        let mut open = self.lock_open();
        if open.contains_key(code) {
            return None;
        }
        tracing::info!(meeting = %code, "relaying a meeting presented on another replica");
        Some(self.insert(&mut open, self.meeting(code, RELAYED, caption)))
    }

    /// A new meeting (not yet open).
    fn meeting(&self, code: &str, presenter: u64, caption: Option<String>) -> Arc<Meeting> {
        Arc::new(Meeting {
            code: code.to_owned(),
            presenter,
            frames: watch::Sender::new(None),
            status: watch::Sender::new(MeetingStatus { caption, followers: 0, ended: None }),
            renders: AtomicU64::new(0),
            metrics: self.metrics.clone(),
            recorded: Mutex::new(None),
            remote_followers: Mutex::default(),
        })
    }

    /// Adds `meeting` to the open ones (`open`, locked) and counts it.
    fn insert(&self, open: &mut HashMap<String, Arc<Meeting>>, meeting: Arc<Meeting>) -> Presenter {
        open.insert(meeting.code.clone(), meeting.clone());
        self.metrics.meetings.set(i64::try_from(open.len()).unwrap_or(i64::MAX));
        self.metrics.meeting_followers.get_or_create(&meeting.labels()).set(0);
        self.metrics.meeting_renders.get_or_create(&meeting.labels()).inc_by(0);
        Presenter { meeting, registry: self.clone() }
    }

    /// The open meeting with join code `given` (typed by a user: case and a dash do not
    /// matter); a 404 saying so when there is none.
    pub fn find(&self, given: &str) -> Result<Arc<Meeting>, ApiError> {
        let unknown = || {
            ApiError::NotFound(format!(
                "no open meeting has the code {:?}; check the code or ask the presenter",
                echo(given)
            ))
        };
        let code = normalize_code(given).ok_or_else(unknown)?;
        self.lock_open().get(&code).cloned().ok_or_else(unknown)
    }

    /// Ends meeting `code` (if open) and tells its followers and presenter `reason`.
    pub fn end(&self, code: &str, reason: &'static str) {
        let mut open = self.lock_open();
        let Some(meeting) = open.remove(code) else { return };
        self.metrics.meetings.set(i64::try_from(open.len()).unwrap_or(i64::MAX));
        drop(open);
        meeting.status.send_modify(|s| s.ended = Some(reason));
        self.metrics.meeting_followers.remove(&meeting.labels());
        self.metrics.meeting_renders.remove(&meeting.labels());
        let recording = meeting.recorded.lock().unwrap_or_else(PoisonError::into_inner).take();
        let (store, code_closed) = (self.store.clone(), code.to_owned());
        in_background(async move {
            if let Some(recording) = recording {
                // Nothing to close when recording failed; the error was logged.
                let _ = recording.await;
            }
            if let Err(error) = store.close_meeting(&code_closed, participation::now_ms()).await {
                tracing::error!(%error, "the meeting's end cannot be recorded");
            }
        });
        tracing::info!(meeting = %code, reason, renders = meeting.renders.load(Ordering::Relaxed), "meeting ended");
    }

    /// Registers WebSocket session `session` so that a meeting can be opened for it over REST.
    pub fn register(&self, session: u64) -> Mailbox {
        let (sender, receiver) = mpsc::channel(2);
        self.lock_sessions().insert(session, sender);
        Mailbox { session, receiver, registry: self.clone() }
    }

    /// Opens a meeting for WebSocket session `session` and hands it to the session.
    pub fn open_for(&self, session: u64, caption: Option<String>) -> Result<Arc<Meeting>, ApiError> {
        let sender = self.lock_sessions().get(&session).cloned().ok_or_else(|| {
            ApiError::NotFound(format!("no WebSocket session {session} is open (the `session` of its `hello` message)"))
        })?;
        let presenter = self.open(session, caption)?;
        let meeting = presenter.meeting.clone();
        // A session that left meanwhile drops the presenter, which ends the meeting again.
        sender
            .try_send(presenter)
            .map_err(|_| ApiError::Conflict(format!("session {session} is closing or busy; open the meeting again")))?;
        Ok(meeting)
    }
}

/// Runs a store write on the runtime, if there is one (a session that ends while the runtime
/// shuts down records nothing).
fn in_background(task: impl Future<Output = ()> + Send + 'static) -> Option<tokio::task::JoinHandle<()>> {
    tokio::runtime::Handle::try_current().ok().map(|runtime| runtime.spawn(task))
}

/// Whether a client may open or close a meeting: the admin guard admitted it (its token, or
/// loopback without one), or it gave the meeting password (`--meeting-password`) or the
/// admin token as `secret`.
pub fn authorize(state: &AppState, admin: Result<Admin, ApiError>, secret: Option<&str>) -> Result<(), ApiError> {
    let config = state.config();
    let Err(refused) = admin else { return Ok(()) };
    match secret {
        Some(given)
            if [&config.meeting_password, &config.admin_token]
                .into_iter()
                .flatten()
                .any(|s| secret_matches(given.trim(), s)) =>
        {
            Ok(())
        }
        Some(_) => Err(ApiError::Forbidden("the meeting password is wrong".into())),
        None if config.meeting_password.is_some() => Err(ApiError::Forbidden(
            "opening a meeting needs the meeting password (`password`) or the admin token".into(),
        )),
        None => Err(refused),
    }
}

/// What a meeting is: `POST /api/meetings` and `GET /api/meetings/{code}`.
#[derive(Debug, Serialize, ToSchema)]
pub struct MeetingInfo {
    /// The join code (6 symbols of `23456789ABCDEFGHJKMNPQRSTUVWXYZ`).
    pub code: String,
    /// The page followers open, relative to the server: `/?meeting=CODE`.
    pub join_url: String,
    /// The join link as QR code (SVG).
    pub qr_url: String,
    /// The presenter's WebSocket session.
    pub presenter_session: u64,
    /// The presenter's caption.
    pub caption: Option<String>,
    /// Sessions following now.
    pub followers: usize,
    /// Frames rendered for the meeting (each once, whatever the number of followers).
    pub renders: u64,
}

/// The body of `POST /api/meetings`.
#[derive(Debug, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct OpenMeeting {
    /// The WebSocket session that presents (the `session` of its `hello` message).
    pub session: u64,
    /// The meeting password (`--meeting-password`), unless the admin token is sent.
    #[serde(default)]
    pub password: Option<String>,
    /// A caption followers see (plain text, at most 500 characters).
    #[serde(default)]
    pub caption: Option<String>,
}

/// Opens a meeting presented by a WebSocket session; the session gets a `meeting` message.
#[utoipa::path(post, path = "/api/meetings", tag = "meetings", request_body = OpenMeeting,
    security((), ("bearer" = [])),
    responses(
        (status = 201, description = "The meeting", body = MeetingInfo),
        (status = 400, description = "Malformed body", body = ErrorBody),
        (status = 401, description = "Neither the admin token nor the meeting password", body = ErrorBody),
        (status = 403, description = "Wrong meeting password, or refused by the admin guard", body = ErrorBody),
        (status = 404, description = "No such WebSocket session", body = ErrorBody),
        (status = 409, description = "The session presents a meeting already", body = ErrorBody),
        (status = 422, description = "Caption too long or with control characters", body = ErrorBody)))]
pub async fn open(
    admin: Result<Admin, ApiError>,
    State(state): State<AppState>,
    body: Result<Bytes, BytesRejection>,
) -> Result<Response, ApiError> {
    let body: OpenMeeting = super::routes::parse_body(body)?;
    authorize(&state, admin, body.password.as_deref())?;
    let caption = caption(body.caption, "caption")?;
    let meeting = state.meetings().open_for(body.session, caption)?;
    Ok((StatusCode::CREATED, Json(meeting.info())).into_response())
}

/// Describes an open meeting.
#[utoipa::path(get, path = "/api/meetings/{code}", tag = "meetings",
    params(("code" = String, Path, description = "Join code")),
    responses(
        (status = 200, description = "The meeting", body = MeetingInfo),
        (status = 404, description = "No open meeting has this code", body = ErrorBody)))]
pub async fn get(State(state): State<AppState>, Path(code): Path<String>) -> Result<Json<MeetingInfo>, ApiError> {
    Ok(Json(super::replicas::find_meeting(&state, &code).await?.info()))
}

/// The absolute join link of a meeting as the client addressed the server (`Host`, and
/// `https` behind a proxy that says `X-Forwarded-Proto: https`).
fn join_link(headers: &HeaderMap, code: &str) -> String {
    let host = headers.get(header::HOST).and_then(|h| h.to_str().ok()).unwrap_or("localhost");
    let https = headers.get("x-forwarded-proto").and_then(|h| h.to_str().ok()) == Some("https");
    format!("{}://{host}{}", if https { "https" } else { "http" }, join_path(code))
}

/// The SVG of a QR code (error correction M) holding `text`.
pub fn qr_svg(text: &str) -> Result<String, ApiError> {
    let code = qrcode::QrCode::new(text.as_bytes()).map_err(|e| ApiError::Internal(format!("QR code: {e}")))?;
    Ok(code
        .render::<qrcode::render::svg::Color>()
        .min_dimensions(256, 256)
        .dark_color(qrcode::render::svg::Color("#000000"))
        .light_color(qrcode::render::svg::Color("#ffffff"))
        .build())
}

/// The meeting's join link (`http://HOST/?meeting=CODE`) as QR code for the audience to scan.
#[utoipa::path(get, path = "/api/meetings/{code}/qr.svg", tag = "meetings",
    params(("code" = String, Path, description = "Join code")),
    responses(
        (status = 200, description = "QR code", content_type = "image/svg+xml", body = String),
        (status = 404, description = "No open meeting has this code", body = ErrorBody)))]
pub async fn qr(
    State(state): State<AppState>,
    Path(code): Path<String>,
    headers: HeaderMap,
) -> Result<Response, ApiError> {
    let meeting = super::replicas::find_meeting(&state, &code).await?;
    let svg = qr_svg(&join_link(&headers, &meeting.code))?;
    Ok(([(header::CONTENT_TYPE, "image/svg+xml"), (header::CACHE_CONTROL, "no-store")], svg).into_response())
}

/// Ends a meeting (admin); its presenter and followers are told.
#[utoipa::path(delete, path = "/api/meetings/{code}", tag = "meetings",
    params(("code" = String, Path, description = "Join code")),
    security(("bearer" = [])),
    responses(
        (status = 204, description = "Ended"),
        (status = 401, description = "Admin token missing or wrong", body = ErrorBody),
        (status = 403, description = "Refused by the admin guard", body = ErrorBody),
        (status = 404, description = "No open meeting has this code", body = ErrorBody)))]
pub async fn delete(
    _admin: Admin,
    State(state): State<AppState>,
    Path(code): Path<String>,
) -> Result<StatusCode, ApiError> {
    let meeting = state.meetings().find(&code)?;
    state.meetings().end(&meeting.code, "an administrator ended the meeting");
    Ok(StatusCode::NO_CONTENT)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn codes_are_six_unambiguous_symbols_and_differ() {
        let codes: Vec<String> = (0..200).map(|_| new_code().expect("code")).collect();
        for code in &codes {
            assert_eq!(code.len(), CODE_LEN);
            assert!(!code.contains(['0', 'O', '1', 'I', 'L']), "{code}");
            assert_eq!(normalize_code(code).as_deref(), Some(code.as_str()));
        }
        let distinct: std::collections::HashSet<_> = codes.iter().collect();
        assert!(distinct.len() >= 199, "{} distinct of 200", distinct.len());
        // Every symbol turns up (200 × 6 draws from 31 symbols).
        assert!(CODE_ALPHABET.iter().all(|s| codes.iter().any(|c| c.as_bytes().contains(s))));
    }

    #[test]
    fn typed_codes_are_normalized_and_impossible_ones_refused() {
        assert_eq!(normalize_code(" abc-def ").as_deref(), Some("ABCDEF"));
        for wrong in ["ABCDE", "ABCDEFG", "ABCDE0", "ABCDEI", "", "ÄBCDEF"] {
            assert_eq!(normalize_code(wrong), None, "{wrong}");
        }
    }

    #[test]
    fn the_meeting_code_is_split_off_the_view_parameters() {
        assert_eq!(split_query("width=64&meeting=abc234&yaw=5"), (Some("abc234".into()), "width=64&yaw=5".into()));
        assert_eq!(split_query("width=64"), (None, "width=64".into()));
        assert_eq!(split_query(""), (None, String::new()));
    }

    #[test]
    fn captions_are_plain_bounded_text() {
        assert_eq!(caption(Some("  The new hedge ".into()), "caption").expect("ok").as_deref(), Some("The new hedge"));
        assert_eq!(caption(Some("   ".into()), "caption").expect("ok"), None);
        assert!(caption(Some("x".repeat(MAX_CAPTION + 1)), "caption").is_err());
        assert!(caption(Some("bell\u{7}".into()), "caption").is_err());
    }

    #[tokio::test]
    async fn a_meeting_fans_one_frame_out_and_ends_with_its_presenter() {
        let dir = tempfile::tempdir().expect("temporary directory");
        let store: Arc<dyn ParticipationStore> =
            Arc::new(participation::SqlStore::open_in(dir.path()).await.expect("store"));
        let meetings = Meetings::new(Metrics::new(), store.clone());
        let presenter = meetings.open(7, Some("Hello".into())).expect("open");
        assert!(matches!(meetings.open(7, None), Err(ApiError::Conflict(_))));
        let code = presenter.meeting.code.clone();
        let found = meetings.find(&code.to_lowercase()).expect("find");
        let (mut a, mut b) = (found.follow(), found.follow());
        assert_eq!(found.status().followers, 2);
        let frame = |id| SharedFrame {
            text: Utf8Bytes::from(format!("frame {id}")),
            binary: Bytes::from(vec![id as u8; 4]),
            frame_id: id,
            view: test_view(),
            eye_height: None,
        };
        for id in 1..=3 {
            presenter.meeting.publish(frame(id));
        }
        // A follower that was not looking sees the newest frame only, and the same bytes.
        a.frames.changed().await.expect("frame");
        let seen = a.frames.borrow_and_update().clone().expect("frame");
        assert_eq!(seen.frame_id, 3);
        b.frames.changed().await.expect("frame");
        let other = b.frames.borrow_and_update().clone().expect("frame");
        assert!(Arc::ptr_eq(&seen, &other));
        assert_eq!(presenter.meeting.info().renders, 3);
        drop(b);
        assert_eq!(found.status().followers, 1);
        drop(presenter);
        a.status.changed().await.expect("status");
        assert_eq!(a.status.borrow().ended, Some("the presenter left"));
        assert!(matches!(meetings.find(&code), Err(ApiError::NotFound(_))));
        // The store has the meeting, closed.
        let deadline = std::time::Instant::now() + std::time::Duration::from_secs(10);
        loop {
            let recorded = store.meeting(&code).await.expect("store");
            if let Some(recorded) = recorded
                && recorded.closed_ms.is_some_and(|closed| closed >= recorded.created_ms)
            {
                assert_eq!(recorded.presenter, "session 7");
                break;
            }
            assert!(std::time::Instant::now() < deadline, "the end was not recorded");
            tokio::time::sleep(std::time::Duration::from_millis(10)).await;
        }
    }

    fn test_view() -> ViewRequest {
        ViewRequest {
            camera: crate::scene::camera::Camera::perspective([0.0; 3], 0.0, 0.0, 60.0),
            width: 4,
            height: 4,
            format: super::super::view::ImageFormat::Jpeg,
            quality: Some(50),
            style: crate::render::Style::default(),
            layer_styles: Default::default(),
            data: Default::default(),
            compare: None,
            comments: None,
        }
    }

    #[test]
    fn the_qr_code_is_an_svg() {
        let svg = qr_svg("http://localhost:8080/?meeting=ABC234").expect("svg");
        assert!(svg.starts_with("<?xml") && svg.contains("<svg") && svg.contains("#000000"), "{}", &svg[..80]);
    }
}
