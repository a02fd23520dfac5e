//! Meetings in a WebSocket session (presenter mode): a session presents (its frames are shared
//! with the followers), follows (it renders nothing and passes the presenter's frames on),
//! or has detached from a meeting it may rejoin.

use super::{Link, SendFailed, ServerMessage, Session};
use crate::api::auth::Admin;
use crate::api::error::ApiError;
use crate::api::meetings::{self, Follower, Meeting, MeetingStatus, Presenter, SharedFrame};
use crate::api::view::ViewRequest;
use crate::render::view_style::ViewStyle;
use axum::body::Bytes;
use axum::extract::ws::close_code;
use axum::extract::ws::{Message, Utf8Bytes};
use serde::Serialize;
use std::sync::Arc;
use tokio::sync::watch;
use utoipa::ToSchema;

/// A session's part in a meeting.
pub(super) enum Role {
    /// It presents: its frames go to the followers.
    Presenting { presenter: Box<Presenter>, status: watch::Receiver<MeetingStatus> },
    /// It shows the presenter's frames.
    Following(Follower),
    /// It left the meeting to explore on its own and may rejoin.
    Detached(Arc<Meeting>),
}

/// What a session in a meeting is told (`meeting` message).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum MeetingRole {
    /// This session presents.
    Presenter,
    /// This session shows the presenter's frames.
    Follower,
    /// This session explores on its own; `rejoin` follows again.
    Detached,
}

/// Something a session in a meeting passes on.
pub(super) enum MeetingEvent {
    /// A new frame of the presenter (followers).
    Frame(Arc<SharedFrame>),
    /// The caption, the audience or the meeting's end changed.
    Status,
}

/// Waits for the next frame or status change of the session's meeting (forever when it
/// follows none and presents none).
pub(super) async fn next_event(role: &mut Option<Role>) -> MeetingEvent {
    match role {
        Some(Role::Following(follower)) => loop {
            tokio::select! {
                // The meeting holds both senders as long as a follower holds the meeting.
                Ok(()) = follower.frames.changed() => {
                    if let Some(frame) = follower.frames.borrow_and_update().clone() {
                        return MeetingEvent::Frame(frame);
                    }
                }
                Ok(()) = follower.status.changed() => {
                    follower.status.borrow_and_update();
                    return MeetingEvent::Status;
                }
            }
        },
        Some(Role::Presenting { status, .. }) => match status.changed().await {
            Ok(()) => MeetingEvent::Status,
            Err(_) => std::future::pending().await,
        },
        Some(Role::Detached(_)) | None => std::future::pending().await,
    }
}

impl Session<'_> {
    /// Whether the session shows a presenter's frames (and renders none of its own).
    pub(super) fn is_following(&self) -> bool {
        matches!(self.meeting, Some(Role::Following(_)))
    }

    /// Refuses a control that changes the view while the session follows a meeting.
    pub(super) fn refuse_while_following(&self) -> Result<(), ApiError> {
        match &self.meeting {
            Some(Role::Following(f)) => Err(ApiError::Conflict(format!(
                "this session follows meeting {}; send `detach` to explore on your own",
                f.meeting.code
            ))),
            _ => Ok(()),
        }
    }

    /// The `meeting` message describing the session's meeting now.
    pub(super) fn meeting_message(&self) -> Option<ServerMessage> {
        let (meeting, role) = match &self.meeting {
            Some(Role::Presenting { presenter, .. }) => (&presenter.meeting, MeetingRole::Presenter),
            Some(Role::Following(f)) => (&f.meeting, MeetingRole::Follower),
            Some(Role::Detached(meeting)) => (meeting, MeetingRole::Detached),
            None => return None,
        };
        let info = meeting.info();
        Some(ServerMessage::Meeting {
            code: info.code,
            role,
            caption: info.caption,
            followers: info.followers,
            join_url: info.join_url,
            qr_url: info.qr_url,
        })
    }

    /// `open_meeting`: the session presents a new meeting, if the client was admitted as
    /// admin when it connected or gives the meeting password or admin token.
    pub(super) fn open_meeting(
        &mut self,
        password: Option<String>,
        token: Option<String>,
        caption: Option<String>,
    ) -> Result<ServerMessage, ApiError> {
        self.refuse_while_following()?;
        let admitted = if self.admitted {
            Ok(Admin)
        } else {
            Err(ApiError::Forbidden(
                "opening a meeting needs `password` (the meeting password) or `token` (the admin token)".into(),
            ))
        };
        meetings::authorize(self.state, admitted, password.or(token).as_deref())?;
        let caption = meetings::caption(caption, "caption")?;
        let presenter = self.state.meetings().open(self.id, caption)?;
        Ok(self.start_presenting(presenter))
    }

    /// Makes the session the presenter of a meeting (opened by it or for it over REST); its
    /// view is rendered again so the followers get a frame at once.
    pub(super) fn start_presenting(&mut self, presenter: Presenter) -> ServerMessage {
        if self.is_following() {
            self.leave_following();
        }
        let status = presenter.meeting.subscribe();
        self.meeting = Some(Role::Presenting { presenter: Box::new(presenter), status });
        self.delivered = None;
        self.meeting_message().unwrap_or_else(|| unreachable!("the session presents"))
    }

    /// `close_meeting`: ends the meeting the session presents.
    pub(super) fn close_meeting(&mut self) -> Result<ServerMessage, ApiError> {
        match self.meeting.take() {
            Some(Role::Presenting { presenter, .. }) => {
                let code = presenter.meeting.code.clone();
                let reason = "the presenter closed the meeting";
                presenter.close(reason);
                Ok(ServerMessage::MeetingEnded { code, reason: reason.into() })
            }
            other => {
                self.meeting = other;
                Err(ApiError::Conflict("this session presents no meeting".into()))
            }
        }
    }

    /// `join`: follows the meeting with join code `code`.
    pub(super) async fn join(&mut self, code: &str) -> Result<ServerMessage, ApiError> {
        if let Some(Role::Presenting { presenter, .. }) = &self.meeting {
            return Err(ApiError::Conflict(format!(
                "this session presents meeting {}; send `close_meeting` first",
                presenter.meeting.code
            )));
        }
        let meeting = crate::api::replicas::find_meeting(self.state, code).await?;
        self.take_slot(true)?;
        Ok(self.follow(&meeting))
    }

    /// Follows `meeting`: the session's own render is dropped and its tour stopped.
    pub(super) fn follow(&mut self, meeting: &Arc<Meeting>) -> ServerMessage {
        self.in_flight = None;
        self.tour = None;
        self.meeting = Some(Role::Following(meeting.follow()));
        self.meeting_message().unwrap_or_else(|| unreachable!("the session follows"))
    }

    /// `detach`: the follower goes on with the presenter's camera and style on its own.
    pub(super) fn detach(&mut self) -> Result<ServerMessage, ApiError> {
        let meeting = match &self.meeting {
            Some(Role::Following(f)) => f.meeting.clone(),
            _ => return Err(ApiError::Conflict("this session follows no meeting".into())),
        };
        self.take_slot(false).map_err(|e| match e {
            ApiError::Busy { message, retry_after } => {
                ApiError::Busy { message: format!("{message}; stay with the meeting and try again later"), retry_after }
            }
            other => other,
        })?;
        self.leave_following();
        self.meeting = Some(Role::Detached(meeting));
        Ok(self.meeting_message().unwrap_or_else(|| unreachable!("the session detached")))
    }

    /// `rejoin`: follows again the meeting the session detached from.
    pub(super) fn rejoin(&mut self) -> Result<ServerMessage, ApiError> {
        let Some(Role::Detached(meeting)) = &self.meeting else {
            return Err(ApiError::Conflict("this session has not detached from a meeting".into()));
        };
        let meeting = meeting.clone();
        if meeting.status().ended.is_some() {
            self.meeting = None;
            return Err(ApiError::NotFound(format!("meeting {} has ended", meeting.code)));
        }
        self.take_slot(true)?;
        Ok(self.follow(&meeting))
    }

    /// `caption`: sets the caption the presenter's followers see.
    pub(super) fn set_meeting_caption(&mut self, text: Option<String>) -> Result<ServerMessage, ApiError> {
        let Some(Role::Presenting { presenter, .. }) = &self.meeting else {
            return Err(ApiError::Conflict("only the presenter of a meeting sets its caption".into()));
        };
        presenter.meeting.set_caption(meetings::caption(text, "text")?);
        Ok(self.meeting_message().unwrap_or_else(|| unreachable!("the session presents")))
    }

    /// Sets the caption of the meeting the session presents, if any (a tour's viewpoint).
    pub(super) fn caption_for_followers(&self, caption: Option<String>) {
        if let Some(Role::Presenting { presenter, .. }) = &self.meeting {
            presenter.meeting.set_caption(caption);
        }
    }

    /// Stops following; the session's own view takes over from the presenter's newest frame.
    fn leave_following(&mut self) {
        if let Some(Role::Following(follower)) = self.meeting.take()
            && let Some(frame) = follower.meeting.latest()
        {
            let view = &frame.view;
            self.view.camera = view.camera;
            self.view.eye_height = frame.eye_height;
            self.view.styles = view.frame_style();
            self.view.requested = ViewStyle::of_frame(&self.view.styles);
            self.view.data = view.data.clone();
            // Frame numbers go on rising across the switch.
            self.frame_id = self.frame_id.max(frame.frame_id);
        }
        self.delivered = None;
    }

    /// Shares a frame the presenter got with the meeting's followers.
    pub(super) fn publish(&self, text: &Utf8Bytes, binary: &Bytes, view: &ViewRequest) {
        if let Some(Role::Presenting { presenter, .. }) = &self.meeting {
            presenter.meeting.publish(SharedFrame {
                text: text.clone(),
                binary: binary.clone(),
                frame_id: self.frame_id,
                view: view.clone(),
                eye_height: self.view.eye_height,
            });
        }
    }

    /// Passes a meeting event on: a frame to a follower, a `meeting` message on a status
    /// change, or `meeting_ended` (a follower then goes on on its own).
    pub(super) async fn on_meeting_event(
        &mut self,
        socket: &mut Link,
        event: MeetingEvent,
    ) -> Result<Option<ServerMessage>, SendFailed> {
        match event {
            MeetingEvent::Frame(frame) => {
                socket.send(Message::Text(frame.text.clone())).await?;
                socket.send(Message::Binary(frame.binary.clone())).await?;
                self.state.metrics().meeting_frames_sent.inc();
                // An audience that only watches is not idle.
                self.last_message = tokio::time::Instant::now();
                Ok(None)
            }
            MeetingEvent::Status => {
                let (code, ended) = match &self.meeting {
                    Some(Role::Following(f)) => (f.meeting.code.clone(), f.meeting.status().ended),
                    Some(Role::Presenting { presenter, .. }) => {
                        (presenter.meeting.code.clone(), presenter.meeting.status().ended)
                    }
                    _ => return Ok(None),
                };
                match ended {
                    Some(reason) => {
                        let ended = ServerMessage::MeetingEnded { code, reason: reason.into() };
                        if self.is_following() {
                            // Going on alone takes a rendering slot; without one the follower
                            // is told so and closed.
                            if let Err(busy) = self.take_slot(false) {
                                socket.send_json(&ended).await?;
                                socket.send_json(&self.reject(busy)).await?;
                                socket
                                    .close(close_code::AGAIN, "the meeting ended; no rendering session is free")
                                    .await;
                                return Err(SendFailed::NoSlot);
                            }
                            self.leave_following();
                        }
                        self.meeting = None;
                        Ok(Some(ended))
                    }
                    None => Ok(self.meeting_message()),
                }
            }
        }
    }
}
