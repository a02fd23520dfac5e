//! Several replicas on one PostgreSQL database (issue #16). Comments, viewpoints and
//! meetings live in the database already ([`crate::store::participation`]); layers and art
//! maps are copied there ([`SharedStore`]). What changes on one replica reaches the others as
//! a `NOTIFY` on the channel [`CHANNEL`](crate::store::shared::CHANNEL): each replica
//! announces the public [`Changed`] messages it sends its own WebSocket sessions
//! ([`AppState::publish`]), and a listener on every other replica copies the layer or art
//! maps named, then tells its sessions the same — within the database's round trip.
//!
//! A listener that lost its connection catches up when it is back: it syncs every layer and
//! the art maps and tells its sessions to reload.
//!
//! A meeting is followed on another replica than its presenter's through a relay there
//! ([`find_meeting`]): the presenter's replica sends the view of each presenter frame, its
//! caption and its end; the relay renders each view once for its followers and reports how
//! many follow. Frames themselves never cross between replicas.

use super::AppState;
use super::artmaps;
use super::comments::CommentJson;
use super::error::ApiError;
use super::events::{self, Change, Changed};
use super::layers::store_error;
use super::meetings::{Meeting, Presenter, RELAYED, SharedFrame, normalize_code};
use super::pool::FrameKind;
use super::view::ViewParams;
use crate::render::art_textures::ArtKind;
use crate::scene::camera_params::Source;
use crate::store::participation::CommentStatus;
use crate::store::shared::{Pulled, SharedError, SharedStore};
use crate::store::{LayerMeta, Store};
use serde::{Deserialize, Serialize};
use sqlx::postgres::PgListener;
use std::collections::{HashMap, HashSet};
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};
use std::time::Duration;
use tokio::sync::{Notify, mpsc};

/// The largest `NOTIFY` payload PostgreSQL takes is 8,000 bytes.
const MAX_PAYLOAD: usize = 7_900;
/// Notices a relay may have waiting (frames beyond are dropped: a newer one follows).
const RELAY_QUEUE: usize = 64;
/// How long a new relay waits for the presenter's replica to send a frame.
const RELAY_ANSWER: Duration = Duration::from_secs(10);
/// How often an idle relay looks whether it still has followers.
const RELAY_IDLE: Duration = Duration::from_secs(30);
use tracing::{debug, info, warn};

/// A change announced to the other replicas: the public [`Changed`] message without the
/// comment itself (a `NOTIFY` payload is at most 8,000 bytes; the comment is read from the
/// shared database).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "what", rename_all = "snake_case")]
enum Notice {
    Comments {
        change: Change,
        id: i64,
    },
    Layers {
        change: Change,
        id: String,
    },
    Viewpoints {
        change: Change,
        name: String,
    },
    Artmaps,
    /// A replica relays meeting `code`: its presenter's replica is to send its frames.
    MeetingWanted {
        code: String,
    },
    /// The presenter of meeting `code` got frame `frame_id` of `view`.
    MeetingFrame {
        code: String,
        frame_id: u32,
        view: Box<ViewParams>,
        eye_height: Option<f32>,
    },
    /// Meeting `code` has this caption, or ended.
    MeetingStatus {
        code: String,
        caption: Option<String>,
        ended: bool,
    },
    /// The sender relays meeting `code` to this many followers.
    MeetingAudience {
        code: String,
        followers: usize,
    },
}

/// What a relay hears of its meeting.
enum RelayNotice {
    Frame { frame_id: u32, view: Box<ViewParams>, eye_height: Option<f32> },
    Status { caption: Option<String>, ended: bool },
}

impl Notice {
    /// The notice of a message sessions are sent; `None` for the `reload` of a session that
    /// fell behind (that concerns one session only).
    fn of(changed: &Changed) -> Option<Notice> {
        Some(match changed {
            Changed::Comments { change, id, .. } => Notice::Comments { change: *change, id: (*id)? },
            Changed::Layers { change, id } => Notice::Layers { change: *change, id: id.clone()? },
            Changed::Viewpoints { change, name } => Notice::Viewpoints { change: *change, name: name.clone()? },
            Changed::Artmaps { .. } => Notice::Artmaps,
        })
    }
}

/// A notice with the replica that sent it (a replica hears its own notices too).
#[derive(Debug, Serialize, Deserialize)]
struct Envelope {
    from: String,
    #[serde(flatten)]
    notice: Notice,
}

/// This replica's part: the shared store, the queue of notices to send, in order, and the
/// meetings relayed from or to other replicas.
pub struct Replication {
    shared: SharedStore,
    replica: String,
    outbox: mpsc::UnboundedSender<String>,
    /// Meetings presented elsewhere and relayed here: where their notices go.
    relays: Mutex<HashMap<String, mpsc::Sender<RelayNotice>>>,
    /// Meetings presented here whose frames go to other replicas: how to ask for the newest
    /// frame again.
    forwards: Mutex<HashMap<String, Arc<Notify>>>,
    /// Meetings relayed here whose end was heard (the database may record it a moment later).
    ended: Mutex<HashSet<String>>,
}

impl Replication {
    /// Opens the shared store when `url` is a PostgreSQL URL (`None` for SQLite: one server);
    /// [`sync`] brings the local store in line with it.
    pub async fn open(url: Option<&str>) -> Result<Option<Replication>, SharedError> {
        let Some(url) = url.filter(|u| u.starts_with("postgres://") || u.starts_with("postgresql://")) else {
            return Ok(None);
        };
        let shared = SharedStore::open(url).await?;
        let mut random = [0u8; 8];
        getrandom::fill(&mut random).map_err(|e| SharedError::Task(e.to_string()))?;
        let replica = super::view::hex(&random);
        let (outbox, mut queue) = mpsc::unbounded_channel::<String>();
        let sender = shared.clone();
        tokio::spawn(async move {
            while let Some(payload) = queue.recv().await {
                if let Err(error) = sender.notify(&payload).await {
                    warn!(%error, "cannot tell the other replicas of a change");
                }
            }
        });
        Ok(Some(Replication {
            shared,
            replica,
            outbox,
            relays: Mutex::default(),
            forwards: Mutex::default(),
            ended: Mutex::default(),
        }))
    }

    /// Queues the notice of `changed` for the other replicas. Layers and art maps are
    /// announced with their writes, inside the transaction ([`Replication::push_layer`],
    /// [`Replication::put_art_map`]), so not again here.
    pub fn announce(&self, changed: &Changed) {
        match Notice::of(changed) {
            Some(Notice::Layers { .. } | Notice::Artmaps) | None => {}
            Some(notice) => self.send(notice),
        }
    }

    /// Queues `notice` for the other replicas.
    fn send(&self, notice: Notice) {
        if let Some(payload) = self.payload(notice) {
            let _ = self.outbox.send(payload);
        }
    }

    /// The `NOTIFY` payload of `notice` from this replica; `None` (with a warning) for one too
    /// large.
    fn payload(&self, notice: Notice) -> Option<String> {
        match serde_json::to_string(&Envelope { from: self.replica.clone(), notice }) {
            Ok(payload) if payload.len() <= MAX_PAYLOAD => Some(payload),
            Ok(payload) => {
                warn!(bytes = payload.len(), "a replica notice is too large for NOTIFY; dropped");
                None
            }
            Err(error) => {
                warn!(%error, "cannot encode a replica notice");
                None
            }
        }
    }

    /// Writes the local store's layer `id` to the shared store (`before`: the version the
    /// local write started from), telling the other replicas with the write, so that they
    /// hear of it even if this one dies right after. When that fails the local copy is made
    /// the shared one again, so the replicas agree, and the error is returned.
    pub async fn push_layer(&self, store: &Arc<Store>, id: &str, before: Option<&LayerMeta>) -> Result<(), ApiError> {
        let change = match (before, store.get(id).is_ok()) {
            (_, false) => Change::Removed,
            (None, true) => Change::Added,
            (Some(_), true) => Change::Changed,
        };
        let notice = self.payload(Notice::Layers { change, id: id.to_owned() });
        let Err(error) = self.shared.push_layer(store, id, before, notice.as_deref()).await else { return Ok(()) };
        if let Err(restore) = self.shared.pull_layer(store, id).await {
            warn!(layer = id, error = %restore, "cannot restore a layer's local copy from the shared database");
        }
        Err(shared_error(error))
    }

    /// Stores (`Some`) or removes (`None`) the uploaded art map `index` of `kind` in the
    /// shared store, telling the other replicas with the write.
    pub async fn put_art_map(&self, kind: ArtKind, index: usize, png: Option<&[u8]>) -> Result<(), SharedError> {
        let notice = self.payload(Notice::Artmaps);
        self.shared.put_art_map(kind, index, png, notice.as_deref()).await
    }
}

/// Brings this replica's local store in line with the shared database (while the server
/// answers, before the scene is ready: copying many layers may take a while).
pub async fn sync(state: &AppState) -> Result<(), SharedError> {
    let Some(replication) = state.replication() else { return Ok(()) };
    let changed = replication.shared.sync(state.store()).await?;
    let (replica, layers) = (&replication.replica, state.store().list().len());
    info!(%replica, layers, synced = changed.len(), "sharing layers and art maps with the other replicas");
    Ok(())
}

/// The API error of a shared-store failure.
pub fn shared_error(error: SharedError) -> ApiError {
    match error {
        SharedError::Local(e) => store_error(e),
        SharedError::Conflict(_) => ApiError::Conflict(error.to_string()),
        SharedError::Database { .. } => ApiError::Busy { message: error.to_string(), retry_after: 5 },
        SharedError::Corrupt { .. } | SharedError::Task(_) => ApiError::Storage(error.to_string()),
    }
}

/// Starts listening for the other replicas' notices (`None` without replicas). Done before
/// [`sync`], so that no change made between the copy and the listening is missed.
pub async fn subscribe(state: &AppState) -> Result<Option<PgListener>, SharedError> {
    match state.replication() {
        Some(replication) => replication.shared.listen().await.map(Some),
        None => Ok(None),
    }
}

/// Applies the other replicas' notices heard by `listener` (from [`subscribe`]) until the
/// server shuts down (see the module documentation).
pub async fn listen(state: AppState, mut listener: PgListener) {
    let Some(replication) = state.replication() else { return };
    let mut stopping = state.shutdown_receiver();
    loop {
        let received = tokio::select! {
            received = listener.try_recv() => received,
            _ = stopping.wait_for(|s| *s) => return,
        };
        match received {
            Ok(Some(notification)) => match serde_json::from_str::<Envelope>(notification.payload()) {
                Ok(envelope) if envelope.from == replication.replica => {}
                Ok(envelope) => apply(&state, replication, &envelope.from, envelope.notice).await,
                Err(error) => warn!(%error, payload = notification.payload(), "ignoring an unreadable replica notice"),
            },
            // The connection was lost (and is back): notices may be missing.
            Ok(None) => catch_up(&state, replication).await,
            Err(error) => {
                warn!(%error, "lost the other replicas' notices; retrying");
                tokio::time::sleep(Duration::from_secs(1)).await;
            }
        }
    }
}

/// Applies the notice of replica `from` here and tells this replica's sessions.
async fn apply(state: &AppState, replication: &Replication, from: &str, notice: Notice) {
    debug!(?notice, "replica notice");
    let changed = match notice {
        Notice::Comments { change: Change::Removed, id } => {
            Changed::Comments { change: Change::Removed, id: Some(id), comment: None }
        }
        Notice::Comments { change, id } => match state.participation().comment(id).await {
            Ok(Some(comment)) if comment.status == CommentStatus::Visible => {
                Changed::Comments { change, id: Some(id), comment: Some(Box::new(CommentJson::public(&comment))) }
            }
            // Changed again since (another notice follows) or gone.
            Ok(_) => return,
            Err(error) => return warn!(%error, comment = id, "cannot read a comment another replica changed"),
        },
        Notice::Layers { change, id } => match replication.shared.pull_layer(state.store(), &id).await {
            Ok(Pulled::Unchanged) => return,
            Ok(_) => Changed::Layers { change, id: Some(id) },
            Err(error) => return warn!(%error, layer = %id, "cannot copy a layer another replica changed"),
        },
        Notice::Viewpoints { change, name } => Changed::Viewpoints { change, name: Some(name) },
        Notice::Artmaps => match adopt_art_maps(state, replication).await {
            Some(changed) => changed,
            None => return,
        },
        Notice::MeetingWanted { code } => return forward(state, replication, &code),
        Notice::MeetingFrame { code, frame_id, view, eye_height } => {
            return to_relay(replication, &code, RelayNotice::Frame { frame_id, view, eye_height }).await;
        }
        Notice::MeetingStatus { code, caption, ended } => {
            return to_relay(replication, &code, RelayNotice::Status { caption, ended }).await;
        }
        Notice::MeetingAudience { code, followers } => {
            if let Ok(meeting) = state.meetings().find(&code) {
                meeting.set_remote_followers(from, followers);
            }
            return;
        }
    };
    state.events().send(changed);
}

/// Copies the shared art maps and gives them to the renderer (once the scene is loaded);
/// the `artmaps` message for the sessions.
async fn adopt_art_maps(state: &AppState, replication: &Replication) -> Option<Changed> {
    let shared = match replication.shared.art_maps().await {
        Ok(shared) => shared,
        Err(error) => {
            warn!(%error, "cannot read the art maps another replica changed");
            return None;
        }
    };
    if let Err(error) = replication.shared.pull_art_maps(state.store(), &shared).await {
        warn!(%error, "cannot copy the art maps another replica changed");
    }
    let ready = state.ready()?;
    artmaps::adopt(ready, &shared).await;
    let (tams, sams) = ready.art.counts();
    Some(Changed::Artmaps { tams, sams })
}

/// After a lost connection: every layer and the art maps synced, every session told to
/// reload.
async fn catch_up(state: &AppState, replication: &Replication) {
    info!("reconnected to the shared database; catching up");
    if let Err(error) = replication.shared.sync(state.store()).await {
        warn!(%error, "cannot sync with the shared database");
    }
    if let Some(changed) = adopt_art_maps(state, replication).await {
        state.events().send(changed);
    }
    for reload in events::reload_all() {
        state.events().send(reload);
    }
}

/// The open meeting with join code `given`: this replica's, or one a session of another
/// replica presents (the shared participation store has it open), which is relayed here
/// from then on: the presenter's replica sends each frame's view, and this replica renders
/// it for its followers.
pub async fn find_meeting(state: &AppState, given: &str) -> Result<Arc<Meeting>, ApiError> {
    let local = state.meetings().find(given);
    let (Err(_), Some(code)) = (&local, normalize_code(given)) else { return local };
    let Some(replication) = state.replication().filter(|_| state.ready().is_some()) else { return local };
    if lock(&replication.ended).contains(&code) {
        return local;
    }
    let record = state.participation().meeting(&code).await.map_err(|e| ApiError::Storage(e.to_string()))?;
    if record.is_none_or(|m| m.closed_ms.is_some()) {
        return local;
    }
    match state.meetings().open_relay(&code, None) {
        Some(presenter) => {
            let meeting = presenter.meeting.clone();
            tokio::spawn(relay(state.clone(), presenter));
            Ok(meeting)
        }
        // Another follower opened the relay meanwhile.
        None => state.meetings().find(&code),
    }
}

/// Relays a meeting presented on another replica until it ends there, its presenter's
/// replica does not answer, or its last follower here leaves.
async fn relay(state: AppState, presenter: Presenter) {
    let (Some(replication), Some(ready)) = (state.replication(), state.ready()) else { return };
    let code = presenter.meeting.code.clone();
    let (sender, mut notices) = mpsc::channel(RELAY_QUEUE);
    lock(&replication.relays).insert(code.clone(), sender);
    replication.send(Notice::MeetingWanted { code: code.clone() });
    let lane = ready.pool.session_lane();
    let mut status = presenter.meeting.subscribe();
    // The first follower may have joined before this task subscribed: report the count now.
    status.mark_changed();
    let (mut answered, mut followed) = (false, false);
    let reason = loop {
        let wait = if answered { RELAY_IDLE } else { RELAY_ANSWER };
        let notice = tokio::select! {
            notice = notices.recv() => notice,
            () = tokio::time::sleep(wait) => {
                if answered { continue } else { break "the presenter's server does not answer" }
            }
            Ok(()) = status.changed() => {
                let followers = status.borrow_and_update().followers;
                replication.send(Notice::MeetingAudience { code: code.clone(), followers });
                followed |= followers > 0;
                if followed && followers == 0 { break "no follower left here" }
                continue;
            }
        };
        // The notices waiting now: statuses applied in order, only the newest frame rendered.
        let (mut frame, mut next, mut end) = (None, notice, None);
        loop {
            match next {
                Some(RelayNotice::Frame { frame_id, view, eye_height }) => frame = Some((frame_id, view, eye_height)),
                Some(RelayNotice::Status { ended: true, .. }) => {
                    lock(&replication.ended).insert(code.clone());
                    end = Some("the presenter ended the meeting");
                    break;
                }
                Some(RelayNotice::Status { caption, .. }) => presenter.meeting.set_caption(caption),
                None => {
                    end = Some("the server is shutting down");
                    break;
                }
            }
            match notices.try_recv() {
                Ok(notice) => next = Some(notice),
                Err(_) => break,
            }
        }
        if let Some((frame_id, view, eye_height)) = frame {
            answered = true;
            match relayed_frame(&state, ready, &lane, frame_id, &view, eye_height).await {
                Ok(frame) => presenter.meeting.publish(frame),
                Err(error) => warn!(meeting = %code, %error, "cannot render a relayed meeting frame"),
            }
        }
        if let Some(reason) = end {
            break reason;
        }
    };
    lock(&replication.relays).remove(&code);
    replication.send(Notice::MeetingAudience { code: code.clone(), followers: 0 });
    presenter.close(reason);
}

/// Renders the view of a relayed frame here: the frame its followers get.
async fn relayed_frame(
    state: &AppState,
    ready: &super::Ready,
    lane: &super::pool::SessionLane,
    frame_id: u32,
    params: &ViewParams,
    eye_height: Option<f32>,
) -> Result<SharedFrame, ApiError> {
    let view = params.normalize(&ready.scene, state.store(), state.limits(), Source::Body)?;
    let view = super::comments::with_pins(state, ready, view).await?;
    let receiver = lane.render(view.clone(), FrameKind::Still).map_err(super::routes::pool_error)?;
    let frame = receiver.await.map_err(|_| ApiError::ShuttingDown)?.map_err(super::routes::pool_error)?;
    let (text, binary) = super::ws::encode_frame(frame_id, 0, true, &view, &frame)
        .ok_or_else(|| ApiError::Internal("cannot encode a frame message".into()))?;
    Ok(SharedFrame { text, binary, frame_id, view, eye_height })
}

/// Passes a meeting notice to its relay here, if there is one.
async fn to_relay(replication: &Replication, code: &str, notice: RelayNotice) {
    let relay = lock(&replication.relays).get(code).cloned();
    if let Some(relay) = relay {
        let _ = relay.send(notice).await;
    }
}

/// Another replica relays meeting `code`: when it is presented here, its frames and status
/// go out from now on (the newest frame at once).
fn forward(state: &AppState, replication: &Replication, code: &str) {
    let Ok(meeting) = state.meetings().find(code) else { return };
    if meeting.presenter == RELAYED {
        return;
    }
    let again = {
        let mut forwards = lock(&replication.forwards);
        if let Some(again) = forwards.get(code) {
            again.notify_one();
            return;
        }
        let again = Arc::new(Notify::new());
        forwards.insert(code.to_owned(), again.clone());
        again
    };
    let state = state.clone();
    tokio::spawn(async move {
        let Some(replication) = state.replication() else { return };
        let code = meeting.code.clone();
        let (mut frames, mut status) = (meeting.watch_frames(), meeting.subscribe());
        frames.mark_changed();
        status.mark_changed();
        loop {
            tokio::select! {
                Ok(()) = frames.changed() => {
                    let frame = frames.borrow_and_update().clone();
                    if let Some(frame) = frame {
                        let (frame_id, eye_height) = (frame.frame_id, frame.eye_height);
                        let view = Box::new(frame.view.to_params());
                        replication.send(Notice::MeetingFrame { code: code.clone(), frame_id, view, eye_height });
                    }
                }
                Ok(()) = status.changed() => {
                    let now = status.borrow_and_update().clone();
                    let ended = now.ended.is_some();
                    replication.send(Notice::MeetingStatus { code: code.clone(), caption: now.caption, ended });
                    if ended { break }
                }
                () = again.notified() => frames.mark_changed(),
                else => break,
            }
        }
        lock(&replication.forwards).remove(&code);
    });
}

fn lock<T>(mutex: &Mutex<T>) -> MutexGuard<'_, T> {
    mutex.lock().unwrap_or_else(PoisonError::into_inner)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn notices_name_what_changed_without_the_comment() {
        let comment = Changed::Comments { change: Change::Added, id: Some(7), comment: None };
        let envelope = Envelope { from: "a1".into(), notice: Notice::of(&comment).expect("notice") };
        let text = serde_json::to_string(&envelope).expect("json");
        assert_eq!(text, r#"{"from":"a1","what":"comments","change":"added","id":7}"#);
        let back: Envelope = serde_json::from_str(&text).expect("parse");
        assert_eq!(back.notice, Notice::Comments { change: Change::Added, id: 7 });
        let art: Envelope = serde_json::from_str(r#"{"from":"b","what":"artmaps"}"#).expect("art");
        assert_eq!(art.notice, Notice::Artmaps);
        for reload in events::reload_all() {
            assert_eq!(Notice::of(&reload), None, "a session's reload stays on its replica");
        }
    }
}
