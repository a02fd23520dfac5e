//! Access control for write endpoints: with an admin token configured they need
//! `Authorization: Bearer <token>`; without one they accept loopback clients only.

use super::AppState;
use super::error::ApiError;
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

impl FromRequestParts<AppState> for Admin {
    type Rejection = ApiError;

    async fn from_request_parts(parts: &mut Parts, state: &AppState) -> Result<Admin, ApiError> {
        match &state.config().admin_token {
            Some(token) => {
                let given = parts
                    .headers
                    .get(header::AUTHORIZATION)
                    .and_then(|v| v.to_str().ok())
                    .and_then(|v| v.strip_prefix("Bearer "))
                    .map(str::trim);
                match given {
                    Some(given) if constant_time_eq(given.as_bytes(), token.as_bytes()) => Ok(Admin),
                    _ => Err(ApiError::Unauthorized),
                }
            }
            None => {
                let peer = parts.extensions.get::<ConnectInfo<SocketAddr>>().map(|ConnectInfo(addr)| addr.ip());
                match peer {
                    Some(ip) if ip.to_canonical().is_loopback() => Ok(Admin),
                    _ => Err(ApiError::Forbidden),
                }
            }
        }
    }
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
        let state = AppState::new(config, std::sync::Arc::new(store));
        let mut request = axum::http::Request::builder().uri("/api/cache/clear");
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
        assert!(matches!(admit(None, "10.0.0.7:5000", None).await, Err(ApiError::Forbidden)));
        assert!(matches!(admit(None, "[2001:db8::1]:5000", Some("Bearer x")).await, Err(ApiError::Forbidden)));
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
