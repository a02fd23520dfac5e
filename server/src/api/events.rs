//! Live updates (issue #14): whatever changes comments, layers, viewpoints or art maps
//! publishes a typed [`LiveEvent`] ([`super::AppState::publish`]); what the public is to know
//! of it goes on a `tokio::sync::broadcast` in the app state (and to the other replicas,
//! [`super::replicas`]), and every WebSocket session forwards it to its client as a
//! [`Changed`] message (`{"type": "changed", "what": "comments" | "layers" | "viewpoints" |
//! "artmaps", …}`), so no page needs a reload.
//!
//! WebSocket sessions are public: a comment that is not visible never reaches them. A comment
//! that becomes visible (approved) arrives as `added`, one that stops being visible (hidden,
//! deleted) as `removed` with its id only.

use super::comments::CommentJson;
use crate::store::participation::{Comment, CommentStatus};
use serde::{Deserialize, Serialize};
use tokio::sync::broadcast;
use utoipa::ToSchema;

/// Events a slow session may fall behind by before it misses some (it is told to reload).
pub const CAPACITY: usize = 256;

/// What happened to the thing an event is about.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum Change {
    /// It is new.
    Added,
    /// It changed (moderation status, likes, reports; a layer's new time step).
    Changed,
    /// It is gone.
    Removed,
    /// The session missed events (it fell behind): fetch the whole list again.
    Reload,
}

/// A change, as sent to every session; the typed form of the channel.
#[derive(Debug, Clone, PartialEq)]
pub enum LiveEvent {
    /// A comment was added, changed (status, likes, reports) or removed.
    Comment {
        /// Added, changed or removed (in the store; [`LiveEvent::public`] turns it into what
        /// the public sees).
        change: Change,
        /// The comment after the change (before it, when removed).
        comment: Box<Comment>,
        /// Whether the public saw the comment before the change.
        was_public: bool,
    },
    /// A data layer was uploaded (added, or a time step appended: changed) or deleted.
    Layer {
        /// Added, changed or removed.
        change: Change,
        /// The layer's id.
        id: String,
    },
    /// A viewpoint was defined, redefined or deleted over the admin API.
    Viewpoint {
        /// Added, changed or removed.
        change: Change,
        /// The viewpoint's name.
        name: String,
    },
    /// The art maps changed: how many there are now.
    ArtMaps {
        /// Tonal art maps.
        tams: usize,
        /// Silhouette art maps.
        sams: usize,
    },
}

/// The `changed` WebSocket message (after `"type": "changed"`), tagged by `what`.
#[derive(Debug, Clone, PartialEq, Serialize, ToSchema)]
#[serde(tag = "what", rename_all = "snake_case")]
pub enum Changed {
    /// A public comment appeared, changed or disappeared (`GET /api/comments`).
    Comments {
        /// `added`, `changed`, `removed` or `reload`.
        change: Change,
        /// The comment's id (absent with `reload`).
        #[serde(skip_serializing_if = "Option::is_none")]
        id: Option<i64>,
        /// The comment as `GET /api/comments/{id}` answers it (absent when removed).
        #[serde(skip_serializing_if = "Option::is_none")]
        comment: Option<Box<CommentJson>>,
    },
    /// A data layer changed (`GET /api/layers`).
    Layers {
        /// `added`, `changed`, `removed` or `reload`.
        change: Change,
        /// The layer's id (absent with `reload`).
        #[serde(skip_serializing_if = "Option::is_none")]
        id: Option<String>,
    },
    /// A viewpoint changed (`GET /api/viewpoints`).
    Viewpoints {
        /// `added`, `changed`, `removed` or `reload`.
        change: Change,
        /// The viewpoint's name (absent with `reload`).
        #[serde(skip_serializing_if = "Option::is_none")]
        name: Option<String>,
    },
    /// The art maps changed (`GET /api/artmaps`); the session's next frame uses them.
    Artmaps {
        /// Tonal art maps now.
        tams: usize,
        /// Silhouette art maps now.
        sams: usize,
    },
}

impl LiveEvent {
    /// What a public session is told: comments only while (or when they stop being) visible;
    /// `None` when the public is not to know.
    pub fn public(&self) -> Option<Changed> {
        Some(match self {
            LiveEvent::Comment { change, comment, was_public } => {
                let now_public = *change != Change::Removed && comment.status == CommentStatus::Visible;
                let change = match (*was_public, now_public) {
                    (false, true) => Change::Added,
                    (true, true) => Change::Changed,
                    (true, false) => Change::Removed,
                    (false, false) => return None,
                };
                let json = (change != Change::Removed).then(|| Box::new(CommentJson::public(comment)));
                Changed::Comments { change, id: Some(comment.id), comment: json }
            }
            LiveEvent::Layer { change, id } => Changed::Layers { change: *change, id: Some(id.clone()) },
            LiveEvent::Viewpoint { change, name } => Changed::Viewpoints { change: *change, name: Some(name.clone()) },
            LiveEvent::ArtMaps { tams, sams } => Changed::Artmaps { tams: *tams, sams: *sams },
        })
    }
}

/// The `reload` messages for a session that fell behind and missed events.
pub fn reload_all() -> [Changed; 3] {
    [
        Changed::Comments { change: Change::Reload, id: None, comment: None },
        Changed::Layers { change: Change::Reload, id: None },
        Changed::Viewpoints { change: Change::Reload, name: None },
    ]
}

/// The channel of public messages ([`LiveEvent::public`]): one sender in the app state, one
/// receiver per session.
#[derive(Debug, Clone)]
pub struct Events {
    sender: broadcast::Sender<Changed>,
}

impl Default for Events {
    fn default() -> Events {
        Events { sender: broadcast::Sender::new(CAPACITY) }
    }
}

impl Events {
    /// Sends `changed` to every session listening now (none listening is fine).
    pub fn send(&self, changed: Changed) {
        let _ = self.sender.send(changed);
    }

    /// A receiver of the messages sent from now on.
    pub fn subscribe(&self) -> broadcast::Receiver<Changed> {
        self.sender.subscribe()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::store::participation::Hit;

    fn comment(status: CommentStatus) -> Box<Comment> {
        Box::new(Comment {
            id: 5,
            number: 2,
            position: [1.0, 2.0, 3.0],
            lon_lat: [8.5, 47.4],
            hit: Hit::Terrain,
            camera: serde_json::json!({}),
            text: "Hedge".into(),
            category: None,
            created_ms: 0,
            author: "a".into(),
            status,
            reports: 0,
            likes: 0,
        })
    }

    #[test]
    fn the_public_sees_comments_only_while_visible() {
        let event = |change, status, was_public| LiveEvent::Comment { change, comment: comment(status), was_public };
        let public = |e: LiveEvent| e.public().map(|c| serde_json::to_value(c).expect("json"));
        let added = public(event(Change::Added, CommentStatus::Visible, false)).expect("added");
        assert_eq!((added["what"].as_str(), added["change"].as_str()), (Some("comments"), Some("added")));
        assert_eq!(added["comment"]["text"], "Hedge");
        assert_eq!(public(event(Change::Added, CommentStatus::Pending, false)), None);
        assert_eq!(public(event(Change::Changed, CommentStatus::Hidden, false)), None);
        let approved = public(event(Change::Changed, CommentStatus::Visible, false)).expect("approved");
        assert_eq!(approved["change"], "added");
        let hidden = public(event(Change::Changed, CommentStatus::Hidden, true)).expect("hidden");
        assert_eq!(hidden, serde_json::json!({"what": "comments", "change": "removed", "id": 5}));
        let deleted = public(event(Change::Removed, CommentStatus::Visible, true)).expect("deleted");
        assert_eq!(deleted["change"], "removed");
        let art = public(LiveEvent::ArtMaps { tams: 4, sams: 2 }).expect("art");
        assert_eq!(art, serde_json::json!({"what": "artmaps", "tams": 4, "sams": 2}));
    }
}
