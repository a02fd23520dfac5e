//! The art-map API (SPEC R11, thesis 8.2.5 "DrawSTAM": stroke textures replaced at run time):
//! list the renderer's tonal and silhouette art maps, download each as a PNG, replace one or
//! add one from an uploaded PNG, and restore a generated map. Writes go through the
//! [`Admin`] guard, are applied by the render worker between frames (the next frame of every
//! REST request and WebSocket session uses them), empty the render cache and change the ETag
//! basis, and are kept in the data directory (`<data-dir>/artmaps/`), so that a restart
//! reloads them.
//!
//! Indices stay stable: a map with a generated default (indices below the generated count)
//! can be replaced and restored; added maps (at the count) can be replaced, and only the last
//! one removed.

use super::auth::Admin;
use super::error::{ApiError, ErrorBody};
use super::events::LiveEvent;
use super::pool::{ArtChange, PoolError, RenderPool};
use super::replicas::shared_error;
use super::routes::pool_error;
use super::view::hex;
use super::{AppState, Ready};
use crate::render::RenderError;
use crate::render::art_textures::{ArtKind, ArtMap, ArtMapSet};
use crate::render::artmaps::{ArtMapError, Sam, Tam};
use crate::store::shared::SharedArtMap;
use crate::store::{Store, StoreError};
use axum::Json;
use axum::body::Bytes;
use axum::extract::rejection::BytesRejection;
use axum::extract::{Path, State};
use axum::http::{HeaderValue, StatusCode, header};
use axum::response::{IntoResponse, Response};
use serde::Serialize;
use sha2::{Digest, Sha256};
use std::collections::BTreeMap;
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};
use tokio::sync::watch;
use tracing::{info, warn};
use utoipa::ToSchema;

/// Largest art-map upload (`PUT` body) in bytes.
pub const MAX_ART_MAP_BYTES: usize = 16 << 20;

/// Where an art map comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum ArtSource {
    /// Generated procedurally at start-up.
    Generated,
    /// Uploaded with `PUT`.
    Uploaded,
}

/// One art map in `GET /api/artmaps`.
#[derive(Debug, Serialize, ToSchema)]
pub struct ArtMapInfo {
    /// `tam` (tonal art map, the style's `hatch_map`) or `sam` (silhouette art map, the
    /// style's `silhouette_map`).
    pub kind: &'static str,
    /// The index styles choose it by.
    pub index: usize,
    /// Width of its PNG in pixels (a TAM: every tone level side by side).
    pub width: u32,
    /// Height of its PNG in pixels (a TAM: one tone image's side).
    pub height: u32,
    /// Tone levels of a TAM, lightest first; stroke styles of a SAM (its four channels).
    pub levels: usize,
    /// `generated` or `uploaded`.
    pub source: ArtSource,
    /// Whether the index has a generated default that `DELETE` restores (else `DELETE`
    /// removes it, when it is the last map of its kind).
    pub has_default: bool,
    /// Where its PNG is.
    pub url: String,
}

/// The PNG shape an uploaded TAM must have.
#[derive(Debug, Serialize, ToSchema)]
pub struct TamShape {
    /// Side of one square tone image in pixels.
    pub size: u32,
    /// Tone levels, lightest first.
    pub levels: usize,
    /// PNG width: `levels` × `size`.
    pub width: u32,
    /// PNG height: `size`.
    pub height: u32,
}

/// `GET /api/artmaps`: every art map, and what an upload must look like.
#[derive(Debug, Serialize, ToSchema)]
pub struct ArtMapList {
    /// Tonal art maps by index.
    pub tams: Vec<ArtMapInfo>,
    /// Silhouette art maps by index.
    pub sams: Vec<ArtMapInfo>,
    /// The shape of an uploaded TAM.
    pub tam_shape: TamShape,
    /// Largest upload in bytes.
    pub max_bytes: usize,
}

/// The server's view of the renderer's art maps: what the worker holds, which maps were
/// uploaded, and a generation counter that WebSocket sessions watch.
pub struct ArtMaps {
    /// The generated maps the renderer started with.
    defaults: ArtMapSet,
    state: Mutex<ArtState>,
    /// Serialises writes, so that renderer, data directory and this record change together.
    writes: tokio::sync::Mutex<()>,
    /// Bumped after every change.
    generation: watch::Sender<u64>,
}

struct ArtState {
    current: ArtMapSet,
    /// SHA-256 of each uploaded PNG by kind and index.
    uploaded: BTreeMap<(ArtKind, usize), [u8; 32]>,
}

impl ArtState {
    /// Identifies the uploaded maps: empty when there are none, so ETags stay as they were.
    fn etag_suffix(&self) -> String {
        if self.uploaded.is_empty() {
            return String::new();
        }
        let mut hash = Sha256::new();
        for ((kind, index), digest) in &self.uploaded {
            hash.update(format!("{}-{index}:", kind.name()));
            hash.update(digest);
        }
        format!("-art{}", hex(&hash.finalize()[..8]))
    }
}

/// What a write changed: the index and, for an upload, the digest of its PNG.
struct Committed {
    kind: ArtKind,
    index: usize,
    upload: Option<[u8; 32]>,
}

impl ArtMaps {
    /// The art maps of a freshly started `pool`, with the uploads stored in `store` applied
    /// (blocking; at start-up). Stored maps that no longer fit (another TAM shape, a gap in
    /// the added indices) are skipped with a warning.
    pub fn restore(pool: &RenderPool, store: &Store) -> ArtMaps {
        let defaults = pool.initial_art_maps().clone();
        let mut state = ArtState { current: defaults.clone(), uploaded: BTreeMap::new() };
        let stored = store.art_maps().unwrap_or_else(|e| {
            warn!(error = %e, "cannot list the stored art maps; starting with the generated ones");
            Vec::new()
        });
        for map in stored {
            let restored = std::fs::read(&map.path)
                .map_err(|e| e.to_string())
                .and_then(|bytes| {
                    let decoded = decode(map.kind, &bytes, tam_levels(&state.current), &map.path.to_string_lossy())
                        .map_err(|e| e.to_string())?;
                    Ok((bytes, decoded))
                })
                .and_then(|(bytes, decoded)| {
                    let receiver = pool
                        .change_art(ArtChange::Set { index: map.index, map: decoded })
                        .map_err(|e| e.to_string())?;
                    let maps = receiver.blocking_recv().map_err(|e| e.to_string())?.map_err(|e| e.to_string())?;
                    Ok((bytes, maps))
                });
            match restored {
                Ok((bytes, maps)) => {
                    state.current = maps;
                    state.uploaded.insert((map.kind, map.index), Sha256::digest(&bytes).into());
                    info!(kind = map.kind.name(), index = map.index, "uploaded art map restored");
                }
                Err(error) => warn!(path = %map.path.display(), %error, "skipping a stored art map"),
            }
        }
        ArtMaps {
            defaults,
            state: Mutex::new(state),
            writes: tokio::sync::Mutex::new(()),
            generation: watch::Sender::new(0),
        }
    }

    fn lock(&self) -> MutexGuard<'_, ArtState> {
        self.state.lock().unwrap_or_else(PoisonError::into_inner)
    }

    /// What an ETag depends on besides the view: `scene_id` and the uploaded art maps.
    pub fn etag_basis(&self, scene_id: &str) -> String {
        format!("{scene_id}{}", self.lock().etag_suffix())
    }

    /// The number of changes so far.
    pub fn generation(&self) -> u64 {
        *self.generation.borrow()
    }

    /// A receiver that sees the generation change after every art-map change.
    pub fn subscribe(&self) -> watch::Receiver<u64> {
        self.generation.subscribe()
    }

    /// How many TAMs and SAMs there are.
    pub fn counts(&self) -> (usize, usize) {
        let state = self.lock();
        (state.current.tams.len(), state.current.sams.len())
    }

    /// Every map with its shape and source.
    pub fn list(&self) -> ArtMapList {
        let state = self.lock();
        let info = |kind: ArtKind, index: usize, (width, height): (u32, u32), levels: usize| ArtMapInfo {
            kind: kind.name(),
            index,
            width,
            height,
            levels,
            source: if state.uploaded.contains_key(&(kind, index)) {
                ArtSource::Uploaded
            } else {
                ArtSource::Generated
            },
            has_default: index < self.defaults.count(kind),
            url: format!("/api/artmaps/{}/{index}.png", kind.name()),
        };
        let tams = state.current.tams.iter().enumerate();
        let sams = state.current.sams.iter().enumerate();
        let levels = tam_levels(&state.current);
        let size = state.current.tams.first().map_or(0, |t| t.size);
        ArtMapList {
            tams: tams
                .map(|(i, t)| info(ArtKind::Tam, i, (t.size * t.levels.len() as u32, t.size), t.levels.len()))
                .collect(),
            sams: sams.map(|(i, s)| info(ArtKind::Sam, i, s.image.dimensions(), 4)).collect(),
            tam_shape: TamShape { size, levels, width: size * levels as u32, height: size },
            max_bytes: MAX_ART_MAP_BYTES,
        }
    }

    /// Records a change the worker made (`maps` is its answer), clears the render cache and
    /// tells the sessions.
    fn commit(&self, ready: &Ready, maps: ArtMapSet, change: Committed) {
        {
            let mut state = self.lock();
            state.current = maps;
            match change.upload {
                Some(digest) => state.uploaded.insert((change.kind, change.index), digest),
                None => state.uploaded.remove(&(change.kind, change.index)),
            };
        }
        let (entries, bytes) = ready.cache.clear();
        self.generation.send_modify(|g| *g += 1);
        info!(
            kind = change.kind.name(),
            index = change.index,
            entries,
            bytes,
            "art maps changed; render cache cleared"
        );
    }
}

/// Gives the renderer the uploaded art maps as another replica stored them (`shared`, from
/// the shared database): maps whose PNG is not the one in use are decoded and set (in index
/// order, so that added maps come at the count), uploaded maps the database lacks go back to
/// their generated default or are removed (last first).
pub async fn adopt(ready: &Ready, shared: &[SharedArtMap]) {
    let art = &ready.art;
    let _write = art.writes.lock().await;
    let uploaded = art.lock().uploaded.clone();
    for map in shared {
        let digest: [u8; 32] = Sha256::digest(&map.png).into();
        if uploaded.get(&(map.kind, map.index)) == Some(&digest) {
            continue;
        }
        let (kind, index, png) = (map.kind, map.index, map.png.clone());
        let levels = tam_levels(&art.lock().current);
        let decoded =
            tokio::task::spawn_blocking(move || decode(kind, &png, levels, &format!("{}/{index}", kind.name())))
                .await
                .map_err(|e| e.to_string())
                .and_then(|d| d.map_err(|e| e.to_string()));
        let applied = match decoded {
            Ok(decoded) => apply(ready, ArtChange::Set { index, map: decoded }).await.map_err(|e| e.to_string()),
            Err(error) => Err(error),
        };
        match applied {
            Ok(maps) => art.commit(ready, maps, Committed { kind, index, upload: Some(digest) }),
            Err(error) => warn!(kind = kind.name(), index, %error, "cannot use an art map another replica stored"),
        }
    }
    for &(kind, index) in uploaded.keys().rev().filter(|k| !shared.iter().any(|m| (m.kind, m.index) == **k)) {
        let change = match art.defaults.get(kind, index) {
            Some(default) => ArtChange::Set { index, map: default },
            None => ArtChange::Remove { kind, index },
        };
        match apply(ready, change).await {
            Ok(maps) => art.commit(ready, maps, Committed { kind, index, upload: None }),
            Err(error) => warn!(kind = kind.name(), index, %error, "cannot restore an art map another replica removed"),
        }
    }
}

/// Tells every WebSocket session how many art maps there are now.
fn publish_counts(state: &AppState, art: &ArtMaps) {
    let (tams, sams) = art.counts();
    state.publish(LiveEvent::ArtMaps { tams, sams });
}

/// Tone levels of the renderer's TAMs (what an uploaded strip is cut into).
fn tam_levels(maps: &ArtMapSet) -> usize {
    maps.tams.first().map_or(1, |t| t.levels.len())
}

/// Decodes an art-map PNG of `kind`: a TAM strip of `levels` tone images or a SAM; `name`
/// stands for the file in errors.
fn decode(kind: ArtKind, bytes: &[u8], levels: usize, name: &str) -> Result<ArtMap, ArtMapError> {
    let name = std::path::Path::new(name);
    Ok(match kind {
        ArtKind::Tam => ArtMap::Tam(Arc::new(Tam::from_png_bytes(bytes, levels, name)?)),
        ArtKind::Sam => ArtMap::Sam(Arc::new(Sam::from_png_bytes(bytes, name)?)),
    })
}

/// The kind and index of a path: `tam`/`sam` and `3` or `3.png`; anything else is a 404.
fn parse_path(kind: &str, index: &str) -> Result<(ArtKind, usize), ApiError> {
    let kind = ArtKind::from_name(kind).ok_or_else(|| {
        ApiError::NotFound(format!("unknown art-map kind {:?}; kinds: tam, sam", crate::echo::echo(kind)))
    })?;
    let number = index.strip_suffix(".png").unwrap_or(index);
    let index =
        number.parse::<usize>().ok().filter(|n| n.to_string() == number).ok_or_else(|| {
            ApiError::NotFound(format!("{:?} is no art-map index (0, 1, …)", crate::echo::echo(index)))
        })?;
    Ok((kind, index))
}

/// Has the worker apply `change`; a change it refuses is a 422 naming the body.
async fn apply(ready: &Ready, change: ArtChange) -> Result<ArtMapSet, ApiError> {
    let receiver = ready.pool.change_art(change).map_err(pool_error)?;
    match receiver.await.map_err(|_| ApiError::ShuttingDown)? {
        Ok(maps) => Ok(maps),
        Err(PoolError::Render(error @ RenderError::ArtMap { .. })) => Err(ApiError::invalid("body", error.to_string())),
        Err(error) => Err(pool_error(error)),
    }
}

/// Runs blocking data-directory work off the async threads.
async fn blocking(work: impl FnOnce() -> Result<(), StoreError> + Send + 'static) -> Result<(), ApiError> {
    tokio::task::spawn_blocking(work)
        .await
        .map_err(|e| ApiError::Storage(e.to_string()))?
        .map_err(|e| ApiError::Storage(e.to_string()))
}

/// Stores the PNG of art map `index` of `kind` (`None`: removes it) after the worker applied
/// the change: in the data directory and, with replicas, in the shared database. When that
/// fails, the worker undoes the change with `undo` and the write fails.
async fn persist(
    state: &AppState,
    ready: &Ready,
    undo: ArtChange,
    (kind, index): (ArtKind, usize),
    png: Option<Bytes>,
) -> Result<(), ApiError> {
    let (store, local) = (state.store().clone(), png.clone());
    let mut written = blocking(move || match local {
        Some(png) => store.save_art_map(kind, index, &png),
        None => store.delete_art_map(kind, index),
    })
    .await;
    if written.is_ok()
        && let Some(replication) = state.replication()
    {
        written = replication.put_art_map(kind, index, png.as_deref()).await.map_err(shared_error);
    }
    if written.is_err()
        && let Err(error) = apply(ready, undo).await
    {
        warn!(%error, "cannot undo an art-map change that was not stored");
    }
    written
}

/// How the worker goes back to `previous` at `index` (`None`: the map was added).
fn undo(kind: ArtKind, index: usize, previous: Option<ArtMap>) -> ArtChange {
    match previous {
        Some(map) => ArtChange::Set { index, map },
        None => ArtChange::Remove { kind, index },
    }
}

/// Every tonal and silhouette art map: kind, index, size, tone levels, generated or
/// uploaded, and the shape an uploaded TAM must have.
#[utoipa::path(get, path = "/api/artmaps", tag = "art maps",
    responses(
        (status = 200, description = "The art maps", body = ArtMapList),
        (status = 503, description = "The scene is still loading", body = ErrorBody)))]
pub async fn list(State(state): State<AppState>) -> Result<Json<ArtMapList>, ApiError> {
    Ok(Json(state.ready().ok_or(ApiError::NotReady)?.art.list()))
}

/// An art map as a PNG in the format uploads take: a TAM as an 8-bit grey strip of its tone
/// levels side by side (lightest first, 255 paper, 0 ink), a SAM as RGBA with one stroke
/// style per channel (ink coverage, 255 full ink; row 0 on the contour).
#[utoipa::path(get, path = "/api/artmaps/{kind}/{index}.png", tag = "art maps",
    params(("kind" = String, Path, description = "`tam` or `sam`"), ("index" = usize, Path, description = "Art-map index")),
    responses(
        (status = 200, description = "The art map", content_type = "image/png"),
        (status = 404, description = "Unknown kind or index", body = ErrorBody),
        (status = 503, description = "The scene is still loading", body = ErrorBody)))]
pub async fn png(
    State(state): State<AppState>,
    Path((kind, index)): Path<(String, String)>,
) -> Result<Response, ApiError> {
    let ready = state.ready().ok_or(ApiError::NotReady)?;
    let (kind, index) = parse_path(&kind, &index)?;
    let map = ready.art.lock().current.get(kind, index).ok_or_else(|| not_found(kind, index))?;
    let png = tokio::task::spawn_blocking(move || {
        let image = match map {
            ArtMap::Tam(tam) => image::DynamicImage::ImageLuma8(tam.to_png_strip()),
            ArtMap::Sam(sam) => image::DynamicImage::ImageRgba8(sam.image.clone()),
        };
        let mut png = Vec::new();
        image.write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png).map(|()| png)
    })
    .await
    .map_err(|e| ApiError::Internal(e.to_string()))?
    .map_err(|e| ApiError::Internal(e.to_string()))?;
    Ok(([(header::CONTENT_TYPE, "image/png"), (header::CACHE_CONTROL, "no-cache")], png).into_response())
}

fn not_found(kind: ArtKind, index: usize) -> ApiError {
    ApiError::NotFound(format!("there is no {kind} {index}; see /api/artmaps"))
}

/// Replaces an art map, or adds one when `index` is the count (admin). The body is a PNG in
/// the format of `GET /api/artmaps/{kind}/{index}.png`; a TAM must have the shape in
/// `tam_shape` of `GET /api/artmaps`, a SAM be at least 8 × 8 pixels. The next frame uses it.
#[utoipa::path(put, path = "/api/artmaps/{kind}/{index}", tag = "art maps",
    params(("kind" = String, Path, description = "`tam` or `sam`"), ("index" = usize, Path, description = "An existing index to replace, or the count to add one")),
    security(("bearer" = []), ()),
    request_body(description = "The PNG", content_type = "image/png"),
    responses(
        (status = 200, description = "Replaced", body = ArtMapInfo),
        (status = 201, description = "Added; `Location` names its PNG", body = ArtMapInfo),
        (status = 401, description = "Admin token missing or wrong", body = ErrorBody),
        (status = 403, description = "Refused: without an admin token, a client not on loopback, a foreign Host or a foreign Origin; with one, a foreign Origin", body = ErrorBody),
        (status = 404, description = "Unknown kind", body = ErrorBody),
        (status = 413, description = "Body larger than the server allows", body = ErrorBody),
        (status = 422, description = "Not a PNG, or a shape that does not fit (the message says what is expected); an index beyond the count", body = ErrorBody),
        (status = 503, description = "The scene is still loading", body = ErrorBody)))]
pub async fn put(
    _admin: Admin,
    State(state): State<AppState>,
    Path((kind, index)): Path<(String, String)>,
    body: Result<Bytes, BytesRejection>,
) -> Result<Response, ApiError> {
    let ready = state.ready().ok_or(ApiError::NotReady)?;
    let (kind, index) = parse_path(&kind, &index)?;
    let body = body.map_err(|e| match e.status() {
        StatusCode::PAYLOAD_TOO_LARGE => {
            ApiError::too_large("body", format!("art maps are at most {MAX_ART_MAP_BYTES} bytes"))
        }
        _ => super::connections::body_error(&e, || ApiError::bad("body", e.body_text())),
    })?;
    let art = &ready.art;
    let _write = art.writes.lock().await;
    let (count, levels, previous) = {
        let state = art.lock();
        (state.current.count(kind), tam_levels(&state.current), state.current.get(kind, index))
    };
    if index > count {
        return Err(ApiError::invalid(
            "index",
            format!("there are {count} {kind}s: replace one of 0..{count} or add one as {count}"),
        ));
    }
    let name = format!("{}/{index}", kind.name());
    let upload = body.clone();
    let permit = state.decode_permit().await?;
    let map = tokio::task::spawn_blocking(move || {
        let _permit = permit;
        decode(kind, &upload, levels, &name)
    })
    .await
    .map_err(|e| ApiError::Internal(e.to_string()))?
    .map_err(|e| ApiError::invalid("body", e.to_string()))?;
    let maps = apply(ready, ArtChange::Set { index, map }).await?;
    let digest: [u8; 32] = Sha256::digest(&body).into();
    persist(&state, ready, undo(kind, index, previous.clone()), (kind, index), Some(body)).await?;
    art.commit(ready, maps, Committed { kind, index, upload: Some(digest) });
    publish_counts(&state, art);
    let info = art.list();
    let listed = match kind {
        ArtKind::Tam => info.tams,
        ArtKind::Sam => info.sams,
    };
    let info = listed.into_iter().nth(index).ok_or_else(|| not_found(kind, index))?;
    let added = previous.is_none();
    let status = if added { StatusCode::CREATED } else { StatusCode::OK };
    let mut response = (status, Json(&info)).into_response();
    if added && let Ok(location) = HeaderValue::from_str(&info.url) {
        response.headers_mut().insert(header::LOCATION, location);
    }
    Ok(response)
}

/// Restores the generated art map at `index` (admin), or removes an added one, which must be
/// the last of its kind (so other indices stay); restoring a map that was never replaced
/// changes nothing. The next frame uses the result.
#[utoipa::path(delete, path = "/api/artmaps/{kind}/{index}", tag = "art maps",
    params(("kind" = String, Path, description = "`tam` or `sam`"), ("index" = usize, Path, description = "Art-map index")),
    security(("bearer" = []), ()),
    responses(
        (status = 204, description = "Restored or removed"),
        (status = 401, description = "Admin token missing or wrong", body = ErrorBody),
        (status = 403, description = "Refused: without an admin token, a client not on loopback, a foreign Host or a foreign Origin; with one, a foreign Origin", body = ErrorBody),
        (status = 404, description = "Unknown kind or index", body = ErrorBody),
        (status = 409, description = "An added map that is not the last of its kind", body = ErrorBody),
        (status = 503, description = "The scene is still loading", body = ErrorBody)))]
pub async fn delete(
    _admin: Admin,
    State(state): State<AppState>,
    Path((kind, index)): Path<(String, String)>,
) -> Result<StatusCode, ApiError> {
    let ready = state.ready().ok_or(ApiError::NotReady)?;
    let (kind, index) = parse_path(&kind, &index)?;
    let art = &ready.art;
    let _write = art.writes.lock().await;
    let (count, previous, uploaded) = {
        let state = art.lock();
        (state.current.count(kind), state.current.get(kind, index), state.uploaded.contains_key(&(kind, index)))
    };
    let previous = previous.ok_or_else(|| not_found(kind, index))?;
    let change = match art.defaults.get(kind, index) {
        Some(_) if !uploaded => return Ok(StatusCode::NO_CONTENT),
        Some(default) => ArtChange::Set { index, map: default },
        None if index + 1 == count => ArtChange::Remove { kind, index },
        None => {
            return Err(ApiError::Conflict(format!(
                "{kind} {index} is not the last one added; remove {kind} {} first, so that indices stay stable",
                count - 1
            )));
        }
    };
    let maps = apply(ready, change).await?;
    persist(&state, ready, ArtChange::Set { index, map: previous }, (kind, index), None).await?;
    art.commit(ready, maps, Committed { kind, index, upload: None });
    publish_counts(&state, art);
    Ok(StatusCode::NO_CONTENT)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn paths_name_a_kind_and_a_canonical_index() {
        assert_eq!(parse_path("tam", "3").expect("tam 3"), (ArtKind::Tam, 3));
        assert_eq!(parse_path("sam", "0.png").expect("sam 0"), (ArtKind::Sam, 0));
        for (kind, index) in [("tim", "0"), ("tam", "x"), ("tam", "03"), ("sam", "-1"), ("tam", "1.jpg")] {
            let error = parse_path(kind, index).expect_err(index);
            assert_eq!(error.status(), StatusCode::NOT_FOUND, "{kind}/{index}");
        }
    }
}
