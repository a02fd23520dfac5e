//! The layer and art-map stores shared by several replicas (issue #16): with a PostgreSQL
//! `--database-url`, the database holds every layer (its metadata and time-step grids) and
//! every uploaded art map, and each replica's data directory is a local copy the renderer
//! reads. A write goes to the local store, then to the database in one transaction; the other
//! replicas hear of it by `NOTIFY` and copy it ([`SharedStore::pull_layer`]).
//!
//! # Tables
//!
//! ```text
//! landsketch_shared(key, value)                  'database' → a random id of this database
//! landsketch_layers(id, meta)                    LayerMeta as JSON
//! landsketch_layer_steps(layer_id, file, data)   one grid per step: the bytes of its step file
//! landsketch_art_maps(kind, idx, png)            the PNG as uploaded
//! ```
//!
//! # Consistency
//!
//! The database is the truth. A layer's row and its steps change in one transaction, so a
//! replica killed mid-upload leaves the old state (its local copy is put right by the next
//! start's [`SharedStore::sync`]). A write states the version it started from; when another
//! replica changed the layer meanwhile the transaction is refused ([`SharedError::Conflict`])
//! and the local copy is pulled again. A data directory that never mirrored this database
//! (the marker `shared.json` names the database id) adds its layers and art maps to it at
//! the first start; afterwards what is not in the database is removed locally.

use super::{LayerMeta, Store, StoreError};
use crate::render::art_textures::ArtKind;
use sqlx::postgres::{PgListener, PgPool, PgPoolOptions};
use sqlx::{Row, Transaction};
use std::collections::BTreeMap;
use std::path::PathBuf;
use std::sync::Arc;
use tracing::{info, warn};

/// The `NOTIFY` channel of replica messages.
pub const CHANNEL: &str = "landsketch";

/// Why a shared-store operation failed.
#[derive(Debug, thiserror::Error)]
pub enum SharedError {
    /// The database cannot be reached or refused a statement → 503.
    #[error("the shared database {url} is unavailable: {message}")]
    Database {
        /// The database URL without credentials.
        url: String,
        /// What the driver said.
        message: String,
    },
    /// Another replica changed the layer while this one wrote it → 409.
    #[error("layer \"{0}\" was changed on another server at the same time; upload again")]
    Conflict(String),
    /// A row that cannot be read back (metadata that is no layer) → 500.
    #[error("the shared database holds an unreadable {what}: {message}")]
    Corrupt {
        /// What was read.
        what: String,
        /// Why it is unreadable.
        message: String,
    },
    /// The local copy could not be written or read.
    #[error(transparent)]
    Local(#[from] StoreError),
    /// A task of the shared store failed (it panicked or could not encode) → 500.
    #[error("a shared-store task failed: {0}")]
    Task(String),
}

impl SharedError {
    /// The HTTP status to answer with.
    pub fn status(&self) -> u16 {
        match self {
            SharedError::Database { .. } => 503,
            SharedError::Conflict(_) => 409,
            SharedError::Corrupt { .. } | SharedError::Task(_) => 500,
            SharedError::Local(e) => e.status(),
        }
    }
}

/// What [`SharedStore::pull_layer`] did to the local copy.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Pulled {
    /// It was the database's already.
    Unchanged,
    /// It was added or replaced.
    Installed,
    /// The layer is gone from the database and was removed.
    Removed,
}

/// An uploaded art map as the database holds it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SharedArtMap {
    /// TAM or SAM.
    pub kind: ArtKind,
    /// Its index.
    pub index: usize,
    /// The PNG.
    pub png: Vec<u8>,
}

/// The layers and art maps in PostgreSQL (see the module documentation).
#[derive(Debug, Clone)]
pub struct SharedStore {
    pool: PgPool,
    url: String,
}

impl SharedStore {
    /// Connects to the PostgreSQL database at `url` and creates the tables it lacks.
    pub async fn open(url: &str) -> Result<SharedStore, SharedError> {
        let redacted = super::participation::redacted(url);
        let pool = PgPoolOptions::new()
            .max_connections(8)
            .connect(url)
            .await
            .map_err(|e| SharedError::Database { url: redacted.clone(), message: e.to_string() })?;
        let shared = SharedStore { pool, url: redacted };
        let mut tx = shared.begin().await?;
        // Two replicas starting at once must not both create the tables.
        shared.run(sqlx::query("SELECT pg_advisory_xact_lock(7105560243)").execute(&mut *tx)).await?;
        shared.run(sqlx::raw_sql(SCHEMA).execute(&mut *tx)).await?;
        shared
            .run(
                sqlx::query(
                    "INSERT INTO landsketch_shared (key, value) VALUES ('database', md5(random()::text)) \
                     ON CONFLICT DO NOTHING",
                )
                .execute(&mut *tx),
            )
            .await?;
        shared.commit(tx, None).await?;
        Ok(shared)
    }

    /// The random id of this database (the same for every replica on it).
    pub async fn database_id(&self) -> Result<String, SharedError> {
        self.run(sqlx::query_scalar("SELECT value FROM landsketch_shared WHERE key = 'database'").fetch_one(&self.pool))
            .await
    }

    /// A listener subscribed to [`CHANNEL`].
    pub async fn listen(&self) -> Result<PgListener, SharedError> {
        let mut listener = self.run(PgListener::connect_with(&self.pool)).await?;
        self.run(listener.listen(CHANNEL)).await?;
        Ok(listener)
    }

    /// Sends `payload` (at most 8,000 bytes) to every replica listening on [`CHANNEL`].
    pub async fn notify(&self, payload: &str) -> Result<(), SharedError> {
        self.run(sqlx::query("SELECT pg_notify($1, $2)").bind(CHANNEL).bind(payload).execute(&self.pool)).await?;
        Ok(())
    }

    /// Writes the local store's layer `id` to the database (or removes it there when it is no
    /// longer stored locally); `before` is the version the local write started from (`None`
    /// for a new layer). Refused with [`SharedError::Conflict`] when the database holds
    /// another version than `before`. `notice` is sent on [`CHANNEL`] with the write: it
    /// reaches the other replicas at the commit, even if this one dies right after.
    pub async fn push_layer(
        &self,
        store: &Store,
        id: &str,
        before: Option<&LayerMeta>,
        notice: Option<&str>,
    ) -> Result<(), SharedError> {
        let now = store.get(id).ok();
        let mut tx = self.begin().await?;
        let row: Option<String> = self
            .run(
                sqlx::query_scalar("SELECT meta FROM landsketch_layers WHERE id = $1 FOR UPDATE")
                    .bind(id)
                    .fetch_optional(&mut *tx),
            )
            .await?;
        let shared = row.map(|text| parse_meta(&text)).transpose()?;
        if shared.as_ref() != before {
            return Err(SharedError::Conflict(before.or(now.as_ref()).map_or(id, |m| m.name.as_str()).to_owned()));
        }
        let Some(meta) = now else {
            self.run(sqlx::query("DELETE FROM landsketch_layers WHERE id = $1").bind(id).execute(&mut *tx)).await?;
            return self.commit(tx, notice).await;
        };
        let text = serde_json::to_string(&meta).map_err(|e| SharedError::Task(e.to_string()))?;
        // A new layer: another replica creating the same id at once waits for this insert and
        // then inserts nothing (a conflict).
        let statement = match before {
            None => "INSERT INTO landsketch_layers (id, meta) VALUES ($1, $2) ON CONFLICT (id) DO NOTHING",
            Some(_) => "UPDATE landsketch_layers SET meta = $2 WHERE id = $1",
        };
        let written = self.run(sqlx::query(statement).bind(id).bind(&text).execute(&mut *tx)).await?;
        if written.rows_affected() != 1 {
            return Err(SharedError::Conflict(meta.name));
        }
        let stored: Vec<String> = self
            .run(
                sqlx::query_scalar("SELECT file FROM landsketch_layer_steps WHERE layer_id = $1")
                    .bind(id)
                    .fetch_all(&mut *tx),
            )
            .await?;
        for step in meta.steps.iter().filter(|s| !stored.contains(&s.file)) {
            let data = tokio::fs::read(store.step_path(id, &step.file))
                .await
                .map_err(|source| StoreError::Io { path: store.step_path(id, &step.file), source })?;
            self.run(
                sqlx::query("INSERT INTO landsketch_layer_steps (layer_id, file, data) VALUES ($1, $2, $3)")
                    .bind(id)
                    .bind(&step.file)
                    .bind(data)
                    .execute(&mut *tx),
            )
            .await?;
        }
        let files: Vec<String> = meta.steps.iter().map(|s| s.file.clone()).collect();
        self.run(
            sqlx::query("DELETE FROM landsketch_layer_steps WHERE layer_id = $1 AND NOT (file = ANY($2))")
                .bind(id)
                .bind(&files)
                .execute(&mut *tx),
        )
        .await?;
        self.commit(tx, notice).await
    }

    /// Makes the local copy of layer `id` the database's: installs it (steps the local copy
    /// has already are kept, the others fetched), or removes it when the database has none.
    pub async fn pull_layer(&self, store: &Arc<Store>, id: &str) -> Result<Pulled, SharedError> {
        let row: Option<String> = self
            .run(
                sqlx::query_scalar("SELECT meta FROM landsketch_layers WHERE id = $1")
                    .bind(id)
                    .fetch_optional(&self.pool),
            )
            .await?;
        let local = store.get(id).ok();
        let Some(meta) = row.map(|text| parse_meta(&text)).transpose()? else {
            if local.is_none() {
                return Ok(Pulled::Unchanged);
            }
            let store = store.clone();
            let id = id.to_owned();
            blocking(move || store.delete(&id).map(drop)).await?;
            return Ok(Pulled::Removed);
        };
        if local.as_ref() == Some(&meta) {
            return Ok(Pulled::Unchanged);
        }
        let stage = {
            let (store, id) = (store.clone(), id.to_owned());
            blocking(move || store.staging_dir(&id)).await?
        };
        let installed = self.fill_stage(store, &meta, local.as_ref(), &stage).await;
        let installed = match installed {
            Ok(()) => {
                let store = store.clone();
                let stage = stage.clone();
                blocking(move || store.install(meta, &stage).map(drop)).await
            }
            Err(e) => Err(e),
        };
        if installed.is_err() {
            let _ = tokio::fs::remove_dir_all(&stage).await;
        }
        installed.map(|()| Pulled::Installed)
    }

    /// Writes the step files of `meta` into `stage`: linked from the local copy `local` where
    /// it has the same step, fetched from the database otherwise.
    async fn fill_stage(
        &self,
        store: &Store,
        meta: &LayerMeta,
        local: Option<&LayerMeta>,
        stage: &std::path::Path,
    ) -> Result<(), SharedError> {
        for step in &meta.steps {
            let target = stage.join(&step.file);
            let kept = local.is_some_and(|l| l.steps.contains(step))
                && tokio::fs::hard_link(store.step_path(&meta.id, &step.file), &target).await.is_ok();
            if kept {
                continue;
            }
            let data: Vec<u8> = self
                .run(
                    sqlx::query_scalar("SELECT data FROM landsketch_layer_steps WHERE layer_id = $1 AND file = $2")
                        .bind(&meta.id)
                        .bind(&step.file)
                        .fetch_one(&self.pool),
                )
                .await?;
            tokio::fs::write(&target, data).await.map_err(|source| StoreError::Io { path: target.clone(), source })?;
        }
        Ok(())
    }

    /// Brings the local store in line with the database at start-up (and after the listener
    /// lost its connection): every layer the database has is pulled; a local layer it lacks
    /// is added to it when this data directory never mirrored this database, removed locally
    /// otherwise. The same for art maps. Returns the ids of the layers that changed locally.
    pub async fn sync(&self, store: &Arc<Store>) -> Result<Vec<String>, SharedError> {
        let database = self.database_id().await?;
        let marker = store.dir().join("shared.json");
        let mirrored = tokio::fs::read(&marker)
            .await
            .ok()
            .and_then(|b| serde_json::from_slice::<serde_json::Value>(&b).ok())
            .is_some_and(|v| v["database"] == database.as_str());
        let ids: Vec<String> =
            self.run(sqlx::query_scalar("SELECT id FROM landsketch_layers").fetch_all(&self.pool)).await?;
        let mut changed = Vec::new();
        for local in store.list().into_iter().filter(|m| !ids.contains(&m.id)) {
            if mirrored {
                let (store, id) = (store.clone(), local.id.clone());
                blocking(move || store.delete(&id).map(drop)).await?;
                changed.push(local.id);
            } else {
                info!(layer = %local.id, "adding a layer of the data directory to the shared database");
                self.push_layer(store, &local.id, None, None).await?;
            }
        }
        for id in ids {
            if self.pull_layer(store, &id).await? != Pulled::Unchanged {
                changed.push(id);
            }
        }
        let shared = self.art_maps().await?;
        for local in store.art_maps()? {
            let png = tokio::fs::read(&local.path)
                .await
                .map_err(|source| StoreError::Io { path: local.path.clone(), source })?;
            match shared.iter().find(|m| (m.kind, m.index) == (local.kind, local.index)) {
                Some(_) => {}
                None if mirrored => {
                    let store = store.clone();
                    blocking(move || store.delete_art_map(local.kind, local.index)).await?;
                }
                None => self.put_art_map(local.kind, local.index, Some(&png), None).await?,
            }
        }
        // Read again: the maps just added are the database's now.
        let shared = if mirrored { shared } else { self.art_maps().await? };
        self.pull_art_maps(store, &shared).await?;
        let text = serde_json::json!({ "database": database }).to_string();
        let store_ = store.clone();
        blocking(move || store_.write_marker(&text)).await?;
        Ok(changed)
    }

    /// Stores (`Some`) or removes (`None`) the uploaded art map `index` of `kind`, sending
    /// `notice` with the write (as [`SharedStore::push_layer`]).
    pub async fn put_art_map(
        &self,
        kind: ArtKind,
        index: usize,
        png: Option<&[u8]>,
        notice: Option<&str>,
    ) -> Result<(), SharedError> {
        let index = i64::try_from(index).map_err(|e| SharedError::Task(e.to_string()))?;
        let query = match png {
            Some(png) => sqlx::query(
                "INSERT INTO landsketch_art_maps (kind, idx, png) VALUES ($1, $2, $3) \
                 ON CONFLICT (kind, idx) DO UPDATE SET png = $3",
            )
            .bind(kind.name())
            .bind(index)
            .bind(png),
            None => sqlx::query("DELETE FROM landsketch_art_maps WHERE kind = $1 AND idx = $2")
                .bind(kind.name())
                .bind(index),
        };
        let mut tx = self.begin().await?;
        self.run(query.execute(&mut *tx)).await?;
        self.commit(tx, notice).await
    }

    /// Every uploaded art map in the database, TAMs before SAMs, each kind by index.
    pub async fn art_maps(&self) -> Result<Vec<SharedArtMap>, SharedError> {
        let rows =
            self.run(sqlx::query("SELECT kind, idx, png FROM landsketch_art_maps").fetch_all(&self.pool)).await?;
        let mut maps = Vec::with_capacity(rows.len());
        for row in rows {
            let corrupt = |message: String| SharedError::Corrupt { what: "art map".into(), message };
            let kind: String = row.try_get("kind").map_err(|e| corrupt(e.to_string()))?;
            let index: i64 = row.try_get("idx").map_err(|e| corrupt(e.to_string()))?;
            let png: Vec<u8> = row.try_get("png").map_err(|e| corrupt(e.to_string()))?;
            let kind = ArtKind::from_name(&kind).ok_or_else(|| corrupt(format!("unknown kind {kind}")))?;
            let index = usize::try_from(index).map_err(|e| corrupt(e.to_string()))?;
            maps.push(SharedArtMap { kind, index, png });
        }
        maps.sort_by_key(|m| (m.kind, m.index));
        Ok(maps)
    }

    /// Makes the local copies of the art maps `shared` (from [`SharedStore::art_maps`]): writes
    /// those that differ, removes those the database lacks.
    pub async fn pull_art_maps(&self, store: &Arc<Store>, shared: &[SharedArtMap]) -> Result<(), SharedError> {
        let local: BTreeMap<(ArtKind, usize), PathBuf> =
            store.art_maps()?.into_iter().map(|m| ((m.kind, m.index), m.path)).collect();
        for map in shared {
            let same = match local.get(&(map.kind, map.index)) {
                Some(path) => tokio::fs::read(path).await.is_ok_and(|png| png == map.png),
                None => false,
            };
            if !same {
                let (store, map) = (store.clone(), map.clone());
                blocking(move || store.save_art_map(map.kind, map.index, &map.png)).await?;
            }
        }
        for &(kind, index) in local.keys().filter(|k| !shared.iter().any(|m| (m.kind, m.index) == **k)) {
            let store = store.clone();
            blocking(move || store.delete_art_map(kind, index)).await?;
        }
        Ok(())
    }

    async fn begin(&self) -> Result<Transaction<'static, sqlx::Postgres>, SharedError> {
        self.run(self.pool.begin()).await
    }

    /// Commits `tx`, with `notice` sent on [`CHANNEL`] (PostgreSQL delivers it at the commit).
    async fn commit(
        &self,
        mut tx: Transaction<'static, sqlx::Postgres>,
        notice: Option<&str>,
    ) -> Result<(), SharedError> {
        if let Some(payload) = notice {
            let notify = sqlx::query("SELECT pg_notify($1, $2)").bind(CHANNEL).bind(payload);
            self.run(notify.execute(&mut *tx)).await?;
        }
        self.run(tx.commit()).await
    }

    /// Awaits a driver call, naming the database in its error.
    async fn run<T>(&self, call: impl Future<Output = Result<T, sqlx::Error>>) -> Result<T, SharedError> {
        call.await.map_err(|e| {
            warn!(url = %self.url, error = %e, "shared database error");
            SharedError::Database { url: self.url.clone(), message: e.to_string() }
        })
    }
}

/// The tables (see the module documentation).
const SCHEMA: &str = "
CREATE TABLE IF NOT EXISTS landsketch_shared (key TEXT PRIMARY KEY, value TEXT NOT NULL);
CREATE TABLE IF NOT EXISTS landsketch_layers (id TEXT PRIMARY KEY, meta TEXT NOT NULL);
CREATE TABLE IF NOT EXISTS landsketch_layer_steps (
    layer_id TEXT NOT NULL REFERENCES landsketch_layers (id) ON DELETE CASCADE,
    file TEXT NOT NULL,
    data BYTEA NOT NULL,
    PRIMARY KEY (layer_id, file)
);
CREATE TABLE IF NOT EXISTS landsketch_art_maps (
    kind TEXT NOT NULL, idx BIGINT NOT NULL, png BYTEA NOT NULL, PRIMARY KEY (kind, idx)
);
";

fn parse_meta(text: &str) -> Result<LayerMeta, SharedError> {
    serde_json::from_str(text).map_err(|e| SharedError::Corrupt { what: "layer".into(), message: e.to_string() })
}

/// Runs local-store work off the async threads.
async fn blocking<T: Send + 'static>(
    work: impl FnOnce() -> Result<T, StoreError> + Send + 'static,
) -> Result<T, SharedError> {
    tokio::task::spawn_blocking(work).await.map_err(|e| SharedError::Task(e.to_string()))?.map_err(SharedError::Local)
}
