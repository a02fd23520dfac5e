//! Serving connections with time limits (D8): what a slow or silent client may hold is
//! bounded in time. Request headers, and the wait for the next request on a kept-alive
//! connection, must arrive within `--header-timeout-s`; a request body within
//! `--body-timeout-s` of its headers; a `Content-Length` above a route's body limit is
//! refused with 413 before any of the body is read.

use super::error::ApiError;
use axum::Router;
use axum::body::{Body, Bytes};
use axum::extract::{Request, State};
use axum::http::header;
use axum::middleware::Next;
use axum::response::{IntoResponse, Response};
use http_body::{Frame, SizeHint};
use hyper_util::rt::{TokioIo, TokioTimer};
use hyper_util::service::TowerToHyperService;
use std::future::Future;
use std::net::SocketAddr;
use std::pin::Pin;
use std::task::{Context, Poll};
use std::time::Duration;
use tokio::net::TcpListener;
use tokio::sync::watch;
use tower_service::Service;

/// Accepts connections until `stopping` turns `true`, then lets open requests finish and
/// returns. Each connection is served by hyper's HTTP/1 with upgrades (WebSockets) and
/// closed when its headers, or the next request on a kept-alive connection, do not arrive
/// within `header_timeout`. With `send_buffer`, each connection's kernel send buffer is that
/// many bytes instead of growing to the system's maximum (4 MiB on Linux): what a client that
/// does not read can hold of the server's memory, and how soon a meeting follower that falls
/// behind skips to the newest frame.
pub async fn serve(
    listener: TcpListener,
    router: Router,
    header_timeout: Duration,
    send_buffer: Option<usize>,
    mut stopping: watch::Receiver<bool>,
) -> std::io::Result<()> {
    let mut make_service = router.into_make_service_with_connect_info::<SocketAddr>();
    let mut connections = tokio::task::JoinSet::new();
    loop {
        let (stream, peer) = tokio::select! {
            accepted = listener.accept() => match accepted {
                Ok(accepted) => accepted,
                Err(error) => {
                    // Out of file descriptors and the like: wait for connections to close.
                    tracing::warn!(%error, "cannot accept a connection");
                    tokio::time::sleep(Duration::from_millis(100)).await;
                    continue;
                }
            },
            Some(_) = connections.join_next() => continue,
            () = stopped(&mut stopping) => break,
        };
        if let Some(bytes) = send_buffer
            && let Err(error) = socket2::SockRef::from(&stream).set_send_buffer_size(bytes)
        {
            tracing::debug!(%peer, %error, "cannot set the send buffer");
        }
        let Ok(service) = make_service.call(peer).await;
        let mut stop = stopping.clone();
        connections.spawn(async move {
            let mut builder = hyper::server::conn::http1::Builder::new();
            builder.timer(TokioTimer::new()).header_read_timeout(header_timeout);
            let connection = builder.serve_connection(TokioIo::new(stream), TowerToHyperService::new(service));
            let mut connection = std::pin::pin!(connection.with_upgrades());
            tokio::select! {
                served = connection.as_mut() => {
                    if let Err(error) = served {
                        tracing::debug!(%peer, %error, "connection ended with an error");
                    }
                    return;
                }
                () = stopped(&mut stop) => connection.as_mut().graceful_shutdown(),
            }
            // Shutting down: the request in progress finishes, then the connection closes.
            if let Err(error) = connection.await {
                tracing::debug!(%peer, %error, "connection ended with an error");
            }
        });
    }
    drop(listener);
    while connections.join_next().await.is_some() {}
    Ok(())
}

/// Completes once the shutdown flag is `true` (or its sender is gone).
pub async fn stopped(flag: &mut watch::Receiver<bool>) {
    // The guard `wait_for` returns must not live across an await.
    let _ = flag.wait_for(|stop| *stop).await.map(|_| ());
}

/// Middleware refusing a request whose `Content-Length` exceeds `limit` (the route's body
/// limit) with 413 before any of the body is read; without it a client could announce and
/// trickle gigabytes until the limit is reached.
pub async fn refuse_oversized(State(limit): State<usize>, request: Request, next: Next) -> Response {
    let announced = request
        .headers()
        .get(header::CONTENT_LENGTH)
        .and_then(|v| v.to_str().ok())
        .and_then(|v| v.trim().parse::<u64>().ok());
    match announced {
        Some(length) if length > limit as u64 => ApiError::too_large(
            "body",
            format!("the body of {length} bytes is larger than the {limit} bytes this endpoint accepts"),
        )
        .into_response(),
        _ => next.run(request).await,
    }
}

/// Middleware giving the request body a deadline of `timeout` from now (the headers have
/// arrived): reading it later fails with [`BodyTimeout`], and the connection closes.
pub async fn body_deadline(State(timeout): State<Duration>, request: Request, next: Next) -> Response {
    let request = request
        .map(|inner| Body::new(DeadlineBody { inner, deadline: Box::pin(tokio::time::sleep(timeout)), timeout }));
    next.run(request).await
}

/// The error for a request body that could not be read: 408 when its deadline passed (a
/// [`BodyTimeout`] in the error's chain), else what `otherwise` makes.
pub fn body_error(error: &(dyn std::error::Error + 'static), otherwise: impl FnOnce() -> ApiError) -> ApiError {
    match std::iter::successors(Some(error), |e| e.source()).find_map(|e| e.downcast_ref::<BodyTimeout>()) {
        Some(timeout) => ApiError::RequestTimeout(timeout.to_string()),
        None => otherwise(),
    }
}

/// The request body did not arrive within `--body-timeout-s`.
#[derive(Debug, thiserror::Error)]
#[error("the request body did not arrive within {} s (--body-timeout-s)", .0.as_secs())]
pub struct BodyTimeout(pub Duration);

/// A body that fails with [`BodyTimeout`] once its deadline has passed.
struct DeadlineBody {
    inner: Body,
    deadline: Pin<Box<tokio::time::Sleep>>,
    timeout: Duration,
}

impl http_body::Body for DeadlineBody {
    type Data = Bytes;
    type Error = axum::Error;

    fn poll_frame(self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<Option<Result<Frame<Bytes>, axum::Error>>> {
        let this = self.get_mut();
        if this.deadline.as_mut().poll(cx).is_ready() {
            return Poll::Ready(Some(Err(axum::Error::new(BodyTimeout(this.timeout)))));
        }
        Pin::new(&mut this.inner).poll_frame(cx)
    }

    fn is_end_stream(&self) -> bool {
        self.inner.is_end_stream()
    }

    fn size_hint(&self) -> SizeHint {
        self.inner.size_hint()
    }
}
