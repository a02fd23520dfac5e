//! Access control for write endpoints: with an admin token configured they need
//! `Authorization: Bearer <token>` and refuse foreign `Origin`s; without one they accept only
//! loopback clients that name a loopback `Host` and, if any, a loopback `Origin`.

use super::AppState;
use super::error::ApiError;
use crate::echo::echo;
use axum::extract::{ConnectInfo, FromRequestParts};
use axum::http::header;
use axum::http::request::Parts;
use sha2::{Digest, Sha256};
use std::net::SocketAddr;

/// Extractor that admits a request to a write endpoint or rejects it with 401/403.
#[derive(Debug, Clone, Copy)]
pub struct Admin;

/// Compares a given token with the configured one in time independent of where they differ
/// and of the tokens' lengths: both are hashed (SHA-256) and the digests are XOR-folded over
/// all 32 bytes, with no early exit the optimiser could introduce.
fn constant_time_eq(given: &[u8], token: &[u8]) -> bool {
    let (a, b) = (Sha256::digest(given), Sha256::digest(token));
    let diff = a.iter().zip(b.iter()).fold(0u8, |acc, (x, y)| std::hint::black_box(acc | (x ^ y)));
    std::hint::black_box(diff) == 0
}

/// Whether a secret a client gave (a meeting password, a token) is `secret`, compared in
/// constant time.
pub fn secret_matches(given: &str, secret: &str) -> bool {
    constant_time_eq(given.as_bytes(), secret.as_bytes())
}

/// Whether `host` (a `Host` header value: a name or address with an optional port) names this
/// machine's loopback interface: `localhost`, `127.0.0.1` or `[::1]`.
fn is_loopback_host(host: &str) -> bool {
    let name = match host.strip_prefix('[') {
        // `[::1]` or `[::1]:port`.
        Some(rest) => match rest.split_once(']') {
            Some((address, port)) if port.is_empty() || is_port(port) => return address == "::1",
            _ => return false,
        },
        None => match host.split_once(':') {
            Some((name, port)) if is_port(port) => name,
            Some(_) => return false,
            None => host,
        },
    };
    name.eq_ignore_ascii_case("localhost") || name == "127.0.0.1"
}

/// Whether `suffix` is `:` followed by a port number.
fn is_port(suffix: &str) -> bool {
    suffix.strip_prefix(':').unwrap_or(suffix).parse::<u16>().is_ok()
}

/// The `host[:port]` of an `Origin` value (`scheme://host[:port]`); `None` for `null` and other
/// values that are no HTTP(S) origin.
fn origin_host(origin: &str) -> Option<&str> {
    let rest = origin.strip_prefix("http://").or_else(|| origin.strip_prefix("https://"))?;
    (!rest.is_empty() && !rest.contains(['/', '?', '#', '@'])).then_some(rest)
}

/// The host the client addressed: the `Host` header, or the authority of an absolute URI.
fn requested_host(parts: &Parts) -> Option<&str> {
    match parts.headers.get(header::HOST) {
        Some(value) => value.to_str().ok(),
        None => parts.uri.authority().map(|a| a.as_str()),
    }
}

/// Why a write without admin token is refused, or `None` when the client is on loopback, named
/// a loopback host and, if it sent an `Origin`, comes from a loopback page. The `Host` check
/// stops DNS rebinding (a foreign name resolving to 127.0.0.1), the `Origin` check cross-site
/// request forgery (a foreign page posting to localhost).
fn tokenless_refusal(parts: &Parts) -> Option<String> {
    const HINT: &str = "set an admin token (--admin-token-file) to accept writes from elsewhere";
    let peer = parts.extensions.get::<ConnectInfo<SocketAddr>>().map(|ConnectInfo(addr)| addr.ip());
    if !peer.is_some_and(|ip| ip.to_canonical().is_loopback()) {
        return Some(format!("without an admin token, writes are accepted from loopback clients only; {HINT}"));
    }
    match requested_host(parts) {
        Some(host) if is_loopback_host(host) => {}
        Some(host) => {
            return Some(format!(
                "without an admin token, writes must address the server as localhost, 127.0.0.1 or [::1], \
                 not Host {:?}; {HINT}",
                echo(host)
            ));
        }
        None => return Some(format!("without an admin token, writes need a loopback Host header; {HINT}")),
    }
    let origin = parts.headers.get(header::ORIGIN)?;
    match origin.to_str().ok().and_then(origin_host) {
        Some(host) if is_loopback_host(host) => None,
        _ => Some(format!(
            "without an admin token, writes from a web page are accepted only from a loopback Origin, \
             not {:?}; {HINT}",
            echo(&String::from_utf8_lossy(origin.as_bytes()))
        )),
    }
}

/// Why a write with a valid token is refused as cross-origin, or `None` when it sent no
/// `Origin`, or the origin is this server's own (its host is the `Host` the client addressed)
/// or one of `--cors-origins`.
fn cross_origin_refusal(parts: &Parts, cors_origins: &[String]) -> Option<String> {
    let origin = parts.headers.get(header::ORIGIN)?;
    let text = origin.to_str().ok();
    let same_origin = text
        .and_then(origin_host)
        .zip(requested_host(parts))
        .is_some_and(|(origin, host)| origin.eq_ignore_ascii_case(host));
    let allowed = text.is_some_and(|text| cors_origins.iter().any(|o| o.trim() == "*" || o.trim() == text));
    (!same_origin && !allowed).then(|| {
        format!(
            "cross-origin write refused: Origin {:?} is neither this server's origin nor one of --cors-origins",
            echo(&String::from_utf8_lossy(origin.as_bytes()))
        )
    })
}

impl FromRequestParts<AppState> for Admin {
    type Rejection = ApiError;

    async fn from_request_parts(parts: &mut Parts, state: &AppState) -> Result<Admin, ApiError> {
        let config = state.config();
        match &config.admin_token {
            Some(token) => {
                let given = parts
                    .headers
                    .get(header::AUTHORIZATION)
                    .and_then(|v| v.to_str().ok())
                    .and_then(|v| v.strip_prefix("Bearer "))
                    .map(str::trim);
                match given {
                    Some(given) if constant_time_eq(given.as_bytes(), token.as_bytes()) => {}
                    _ => return Err(ApiError::Unauthorized),
                }
                match cross_origin_refusal(parts, &config.cors_origins) {
                    None => Ok(Admin),
                    Some(why) => Err(ApiError::Forbidden(why)),
                }
            }
            None => match tokenless_refusal(parts) {
                None => Ok(Admin),
                Some(why) => Err(ApiError::Forbidden(why)),
            },
        }
    }
}

/// `GET /api/auth`: this client may change shared state (upload, delete, edit art maps).
#[derive(Debug, serde::Serialize, utoipa::ToSchema)]
pub struct AuthInfo {
    /// Whether the server has an admin token (else it admits loopback clients without one).
    pub token_required: bool,
}

/// Checks a planner's login: 200 when the request would pass every write endpoint's guard
/// (the admin token, or a loopback client on a server without one), 401/403 as they would
/// answer. The browser UI asks this before it shows the planner's controls.
#[utoipa::path(get, path = "/api/auth", tag = "operations",
    security(("bearer" = []), ()),
    responses(
        (status = 200, description = "Writes are admitted", body = AuthInfo),
        (status = 401, description = "Admin token missing or wrong", body = super::error::ErrorBody),
        (status = 403, description = "Refused as a write would be: a client not on loopback, a foreign Host or Origin", body = super::error::ErrorBody)))]
pub async fn check(_admin: Admin, axum::extract::State(state): axum::extract::State<AppState>) -> axum::Json<AuthInfo> {
    axum::Json(AuthInfo { token_required: state.config().admin_token.is_some() })
}

#[cfg(test)]
mod tests {
    use super::super::ServerConfig;
    use super::*;
    use clap::Parser;

    async fn admit(token: Option<&str>, peer: &str, authorization: Option<&str>) -> Result<Admin, ApiError> {
        let mut config = ServerConfig::try_parse_from(["serve"]).expect("defaults");
        config.admin_token = token.map(str::to_owned);
        let dir = tempfile::tempdir().expect("temporary directory");
        let store = crate::store::Store::open(dir.path()).expect("store");
        let participation =
            crate::store::participation::SqlStore::open_in(dir.path()).await.expect("participation store");
        let state = AppState::new(config, std::sync::Arc::new(store), std::sync::Arc::new(participation), None);
        let mut request = axum::http::Request::builder().uri("/api/cache/clear").header(header::HOST, "127.0.0.1:8080");
        if let Some(value) = authorization {
            request = request.header(header::AUTHORIZATION, value);
        }
        let (mut parts, ()) = request.body(()).expect("request").into_parts();
        parts.extensions.insert(ConnectInfo(peer.parse::<SocketAddr>().expect("address")));
        Admin::from_request_parts(&mut parts, &state).await
    }

    #[test]
    fn token_comparison_is_exact() {
        assert!(constant_time_eq(b"s3cret", b"s3cret"));
        assert!(constant_time_eq(b"", b""));
        for wrong in [&b"s3cre"[..], b"s3cret2", b"S3cret", b"s3creu", b"", b"\0s3cret"] {
            assert!(!constant_time_eq(wrong, b"s3cret"), "{wrong:?}");
        }
        let long = vec![b'x'; 4096];
        let mut flipped = long.clone();
        flipped[4095] ^= 1;
        assert!(constant_time_eq(&long, &long.clone()) && !constant_time_eq(&flipped, &long));
    }

    #[tokio::test]
    async fn without_a_token_only_loopback_clients_may_write() {
        assert!(admit(None, "127.0.0.1:5000", None).await.is_ok());
        assert!(admit(None, "[::1]:5000", None).await.is_ok());
        assert!(admit(None, "[::ffff:127.0.0.1]:5000", None).await.is_ok());
        assert!(matches!(admit(None, "10.0.0.7:5000", None).await, Err(ApiError::Forbidden(_))));
        assert!(matches!(admit(None, "[2001:db8::1]:5000", Some("Bearer x")).await, Err(ApiError::Forbidden(_))));
    }

    #[test]
    fn loopback_hosts_and_origins() {
        for host in ["localhost", "LOCALHOST:8080", "127.0.0.1", "127.0.0.1:80", "[::1]", "[::1]:8080"] {
            assert!(is_loopback_host(host), "{host}");
        }
        for host in
            ["attacker.example", "localhost.attacker.example", "127.0.0.1.nip.io", "[::1]x", "localhost:x", "", "[::2]"]
        {
            assert!(!is_loopback_host(host), "{host}");
        }
        assert_eq!(origin_host("http://localhost:8080"), Some("localhost:8080"));
        assert_eq!(origin_host("https://[::1]"), Some("[::1]"));
        for origin in ["null", "file://", "http://", "http://a@localhost", "ftp://localhost"] {
            assert_eq!(origin_host(origin), None, "{origin}");
        }
    }

    #[tokio::test]
    async fn with_a_token_every_client_needs_it() {
        let token = Some("s3cret");
        assert!(admit(token, "10.0.0.7:5000", Some("Bearer s3cret")).await.is_ok());
        for wrong in [None, Some("Bearer s3cre"), Some("Bearer s3cret2"), Some("Basic s3cret"), Some("s3cret")] {
            assert!(matches!(admit(token, "127.0.0.1:5000", wrong).await, Err(ApiError::Unauthorized)), "{wrong:?}");
        }
    }
}
