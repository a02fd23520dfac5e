//! WebSocket clients for the API tests: connect, receive JSON messages and binary frames,
//! send controls.

use super::server::TestServer;
use futures_util::{SinkExt, StreamExt};
use landsketch::api::ws::{FrameHeader, HEADER_LEN};
use serde_json::Value;
use std::time::Duration;
use tokio::net::TcpStream;
use tokio_tungstenite::tungstenite::Message;
use tokio_tungstenite::{MaybeTlsStream, WebSocketStream};

pub type Socket = WebSocketStream<MaybeTlsStream<TcpStream>>;

pub enum Incoming {
    Json(Value),
    Frame(FrameHeader, Vec<u8>),
    Closed(Option<String>),
}

pub async fn connect(server: &TestServer, query: &str) -> Socket {
    let (socket, _) = tokio_tungstenite::connect_async(server.ws_url(query)).await.expect("WebSocket connect");
    socket
}

/// [`connect`] with a receive buffer of `bytes` (set before connecting, so the TCP window
/// stays that small): a client whose buffers fill after a few frames when it does not read.
pub async fn connect_with_receive_buffer(server: &TestServer, query: &str, bytes: u32) -> Socket {
    let address = server.url("").trim_start_matches("http://").trim_end_matches('/').to_string();
    let address: std::net::SocketAddr = address.parse().expect("loopback address");
    let tcp = tokio::net::TcpSocket::new_v4().expect("socket");
    tcp.set_recv_buffer_size(bytes).expect("SO_RCVBUF");
    let stream = tcp.connect(address).await.expect("TCP connect");
    let (socket, _) = tokio_tungstenite::client_async(server.ws_url(query), MaybeTlsStream::Plain(stream))
        .await
        .expect("WebSocket handshake");
    socket
}

pub async fn receive(socket: &mut Socket) -> Incoming {
    loop {
        let message = tokio::time::timeout(Duration::from_secs(30), socket.next()).await.expect("a message in time");
        match message {
            Some(Ok(Message::Text(text))) => {
                return Incoming::Json(serde_json::from_str(text.as_str()).expect("JSON message"));
            }
            Some(Ok(Message::Binary(bytes))) => {
                let header = FrameHeader::decode(&bytes).expect("frame header");
                return Incoming::Frame(header, bytes[HEADER_LEN..].to_vec());
            }
            Some(Ok(Message::Close(frame))) => return Incoming::Closed(frame.map(|f| f.reason.to_string())),
            Some(Ok(_)) => {}
            Some(Err(_)) | None => return Incoming::Closed(None),
        }
    }
}

/// The next frame: its `frame` message, header and image bytes (other JSON messages are
/// returned in the first vector).
pub async fn next_frame(socket: &mut Socket) -> (Vec<Value>, Value, FrameHeader, Vec<u8>) {
    let mut others = Vec::new();
    loop {
        match receive(socket).await {
            Incoming::Json(v) if v["type"] == "frame" => match receive(socket).await {
                Incoming::Frame(header, bytes) => return (others, v, header, bytes),
                _ => panic!("a frame message is followed by a binary frame"),
            },
            Incoming::Json(v) => others.push(v),
            Incoming::Frame(..) => panic!("binary frame without a frame message"),
            Incoming::Closed(reason) => panic!("closed: {reason:?}"),
        }
    }
}

pub async fn send(socket: &mut Socket, message: Value) {
    socket.send(Message::text(message.to_string())).await.expect("send");
}

/// Reads until a JSON message of `kind`; returns it and the other JSON messages before it
/// (binary frames are skipped).
pub async fn until(socket: &mut Socket, kind: &str) -> (Value, Vec<Value>) {
    let mut others = Vec::new();
    loop {
        match receive(socket).await {
            Incoming::Json(v) if v["type"] == kind => return (v, others),
            Incoming::Json(v) => others.push(v),
            Incoming::Frame(..) => {}
            Incoming::Closed(reason) => panic!("closed waiting for {kind}: {reason:?}"),
        }
    }
}

/// The next `changed` message of a session (frames and other messages are skipped); `None`
/// when none comes within `wait`.
pub async fn next_changed(socket: &mut Socket, wait: Duration) -> Option<Value> {
    let deadline = tokio::time::Instant::now() + wait;
    loop {
        let message = tokio::time::timeout_at(deadline, socket.next()).await.ok()??.expect("message");
        if let Message::Text(text) = message {
            let value: Value = serde_json::from_str(&text).expect("JSON");
            if value["type"] == "changed" {
                return Some(value);
            }
        }
    }
}
