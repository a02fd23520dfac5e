//! [`ParticipationStore`] on SQLite or PostgreSQL through sqlx's `Any` driver: one set of
//! portable statements (numbered `$n` parameters, `ON CONFLICT DO NOTHING`, `RETURNING`), the
//! driver chosen by the URL's scheme.

use super::{
    Comment, CommentFilter, CommentStatus, Hit, LikeOutcome, Meeting, NewComment, ParticipationError,
    ParticipationStore, ReportOutcome, StoreFuture, StoredViewpoint,
};
use sqlx::any::{AnyPoolOptions, AnyRow};
use sqlx::{AnyPool, Row};
use std::path::Path;

/// The migrations in `migrations/`, compiled in.
static MIGRATOR: sqlx::migrate::Migrator = sqlx::migrate!();

/// Attempts at a random id before an insert gives up (two ids collide with odds of 2⁻⁵³).
const ID_ATTEMPTS: usize = 4;

/// The columns of a comment row, in the order [`comment_of`] reads them, for a query on
/// `comments c` followed by `$tail`.
macro_rules! select_comments {
    ($tail:literal) => {
        concat!(
            "SELECT c.id, c.number, c.x, c.y, c.z, c.lon, c.lat, c.hit_kind, c.hit_layer, c.hit_plant, ",
            "c.camera, c.body, c.category, c.created_ms, c.author, c.status, c.reports, ",
            "(SELECT COUNT(*) FROM likes l WHERE l.comment_id = c.id) AS likes FROM comments c ",
            $tail
        )
    };
}

/// The participation store in a SQL database (SQLite file or PostgreSQL).
pub struct SqlStore {
    pool: AnyPool,
}

/// The URL of the SQLite database file `path` (created if missing).
pub fn sqlite_url(path: &Path) -> String {
    // sqlx percent-decodes the file name: encode what would end or escape it.
    let name = path.to_string_lossy().replace('%', "%25").replace('?', "%3F").replace('#', "%23");
    format!("sqlite://{name}?mode=rwc")
}

/// A URL for messages: the scheme and host, never a password.
pub(crate) fn redacted(url: &str) -> String {
    match url.split_once("://") {
        Some((scheme, rest)) => {
            let host = rest.rsplit_once('@').map_or(rest, |(_, host)| host);
            format!("{scheme}://{}", host.split(['?', '/']).next().unwrap_or_default())
        }
        None => "(not a URL)".into(),
    }
}

impl SqlStore {
    /// Connects to `url` (`sqlite://…` or `postgres://…`), switches SQLite to write-ahead
    /// logging and runs the migrations.
    pub async fn open(url: &str) -> Result<SqlStore, ParticipationError> {
        sqlx::any::install_default_drivers();
        let sqlite = url.starts_with("sqlite:");
        // One SQLite connection serialises the writes (no busy retries); PostgreSQL takes more.
        let connections = if sqlite { 1 } else { 8 };
        let open_error = |e: sqlx::Error| ParticipationError::Open { url: redacted(url), message: e.to_string() };
        let pool = AnyPoolOptions::new().max_connections(connections).connect(url).await.map_err(open_error)?;
        if sqlite {
            sqlx::query("PRAGMA journal_mode = WAL").execute(&pool).await.map_err(open_error)?;
        }
        MIGRATOR.run(&pool).await.map_err(|e| ParticipationError::Migrate(e.to_string()))?;
        Ok(SqlStore { pool })
    }

    /// Opens (or creates) the SQLite file `participation.sqlite` in `data_dir`.
    pub async fn open_in(data_dir: &Path) -> Result<SqlStore, ParticipationError> {
        SqlStore::open(&sqlite_url(&data_dir.join("participation.sqlite"))).await
    }

    /// Closes the connections (waits for running queries).
    pub async fn close(&self) {
        self.pool.close().await;
    }

    async fn fetch_comment(&self, id: i64) -> Result<Option<Comment>, ParticipationError> {
        let row = sqlx::query(select_comments!("WHERE c.id = $1")).bind(id).fetch_optional(&self.pool).await?;
        row.as_ref().map(comment_of).transpose()
    }
}

/// A random id below 2⁵³ (exact in JavaScript numbers), positive.
fn random_id() -> Result<i64, ParticipationError> {
    let bits = getrandom::u64().map_err(|e| ParticipationError::Database(format!("no random numbers: {e}")))?;
    // 53 bits fit i64; 0 is avoided so that ids are truthy in every client.
    Ok(i64::try_from(bits >> 11).unwrap_or(1).max(1))
}

fn comment_of(row: &AnyRow) -> Result<Comment, ParticipationError> {
    let status: String = row.try_get("status")?;
    let status = CommentStatus::parse(&status)
        .ok_or_else(|| ParticipationError::Corrupt(format!("comment status {status:?}")))?;
    let kind: String = row.try_get("hit_kind")?;
    let hit = match kind.as_str() {
        "terrain" => Hit::Terrain,
        "plant" => {
            let layer: Option<String> = row.try_get("hit_layer")?;
            let index: Option<i64> = row.try_get("hit_plant")?;
            match (layer, index.and_then(|i| u32::try_from(i).ok())) {
                (Some(layer), Some(index)) => Hit::Plant { layer, index },
                _ => return Err(ParticipationError::Corrupt("a plant hit without layer or index".into())),
            }
        }
        other => return Err(ParticipationError::Corrupt(format!("hit kind {other:?}"))),
    };
    let camera: String = row.try_get("camera")?;
    let camera = serde_json::from_str(&camera).map_err(|e| ParticipationError::Corrupt(format!("camera: {e}")))?;
    Ok(Comment {
        id: row.try_get("id")?,
        number: row.try_get("number")?,
        position: [row.try_get("x")?, row.try_get("y")?, row.try_get("z")?],
        lon_lat: [row.try_get("lon")?, row.try_get("lat")?],
        hit,
        camera,
        text: row.try_get("body")?,
        category: row.try_get("category")?,
        created_ms: row.try_get("created_ms")?,
        author: row.try_get("author")?,
        status,
        reports: row.try_get("reports")?,
        likes: row.try_get("likes")?,
    })
}

fn is_unique_violation(error: &sqlx::Error) -> bool {
    matches!(error, sqlx::Error::Database(e) if e.is_unique_violation())
}

impl ParticipationStore for SqlStore {
    fn add_comment(&self, comment: NewComment) -> StoreFuture<'_, Comment> {
        Box::pin(async move {
            let (kind, layer, plant) = match &comment.hit {
                Hit::Terrain => ("terrain", None, None),
                Hit::Plant { layer, index } => ("plant", Some(layer.clone()), Some(i64::from(*index))),
            };
            let camera = comment.camera.to_string();
            for _ in 0..ID_ATTEMPTS {
                let id = random_id()?;
                let mut tx = self.pool.begin().await?;
                // The counter row's lock orders concurrent inserts (PostgreSQL replicas).
                let number: i64 = sqlx::query_scalar(
                    "UPDATE counters SET value = value + 1 WHERE name = 'comment_number' RETURNING value",
                )
                .fetch_one(&mut *tx)
                .await?;
                let inserted = sqlx::query(
                    "INSERT INTO comments (id, number, x, y, z, lon, lat, hit_kind, hit_layer, hit_plant, camera, \
                     body, category, created_ms, author, status, reports) \
                     VALUES ($1, $2, $3, $4, $5, $6, $7, $8, $9, $10, $11, $12, $13, $14, $15, $16, 0)",
                )
                .bind(id)
                .bind(number)
                .bind(comment.position[0])
                .bind(comment.position[1])
                .bind(comment.position[2])
                .bind(comment.lon_lat[0])
                .bind(comment.lon_lat[1])
                .bind(kind)
                .bind(layer.clone())
                .bind(plant)
                .bind(camera.clone())
                .bind(comment.text.clone())
                .bind(comment.category.clone())
                .bind(comment.created_ms)
                .bind(comment.author.clone())
                .bind(comment.status.name())
                .execute(&mut *tx)
                .await;
                match inserted {
                    Ok(_) => {
                        tx.commit().await?;
                        return self
                            .fetch_comment(id)
                            .await?
                            .ok_or_else(|| ParticipationError::Database("the inserted comment is gone".into()));
                    }
                    Err(e) if is_unique_violation(&e) => continue,
                    Err(e) => return Err(e.into()),
                }
            }
            Err(ParticipationError::Database("no free comment id after several attempts".into()))
        })
    }

    fn comment(&self, id: i64) -> StoreFuture<'_, Option<Comment>> {
        Box::pin(self.fetch_comment(id))
    }

    fn comments(&self, filter: CommentFilter) -> StoreFuture<'_, Vec<Comment>> {
        Box::pin(async move {
            let wants = |s: CommentStatus| i64::from(filter.statuses.is_empty() || filter.statuses.contains(&s));
            let rows = sqlx::query(select_comments!(
                "WHERE ($1 IS NULL OR c.category = $1) AND ($2 IS NULL OR c.created_ms >= $2) \
                 AND ($3 IS NULL OR c.created_ms <= $3) \
                 AND ((c.status = 'visible' AND $4 <> 0) OR (c.status = 'pending' AND $5 <> 0) \
                 OR (c.status = 'hidden' AND $6 <> 0)) ORDER BY c.number"
            ))
            .bind(filter.category.clone())
            .bind(filter.since_ms)
            .bind(filter.until_ms)
            .bind(wants(CommentStatus::Visible))
            .bind(wants(CommentStatus::Pending))
            .bind(wants(CommentStatus::Hidden))
            .fetch_all(&self.pool)
            .await?;
            rows.iter().map(comment_of).collect()
        })
    }

    fn set_status(&self, id: i64, status: CommentStatus) -> StoreFuture<'_, Option<Comment>> {
        Box::pin(async move {
            sqlx::query("UPDATE comments SET status = $1 WHERE id = $2")
                .bind(status.name())
                .bind(id)
                .execute(&self.pool)
                .await?;
            self.fetch_comment(id).await
        })
    }

    fn delete_comment(&self, id: i64) -> StoreFuture<'_, Option<Comment>> {
        Box::pin(async move {
            let Some(comment) = self.fetch_comment(id).await? else { return Ok(None) };
            let mut tx = self.pool.begin().await?;
            sqlx::query("DELETE FROM likes WHERE comment_id = $1").bind(id).execute(&mut *tx).await?;
            sqlx::query("DELETE FROM reports WHERE comment_id = $1").bind(id).execute(&mut *tx).await?;
            let deleted = sqlx::query("DELETE FROM comments WHERE id = $1").bind(id).execute(&mut *tx).await?;
            tx.commit().await?;
            Ok((deleted.rows_affected() > 0).then_some(comment))
        })
    }

    fn like(&self, id: i64, author: &str, now_ms: i64) -> StoreFuture<'_, LikeOutcome> {
        let author = author.to_owned();
        Box::pin(async move {
            let mut tx = self.pool.begin().await?;
            let owner: Option<String> = sqlx::query_scalar("SELECT author FROM comments WHERE id = $1")
                .bind(id)
                .fetch_optional(&mut *tx)
                .await?;
            let outcome = match owner {
                None => LikeOutcome::NoComment,
                Some(owner) if owner == author => LikeOutcome::OwnComment,
                Some(_) => {
                    let added = sqlx::query(
                        "INSERT INTO likes (comment_id, author, created_ms) VALUES ($1, $2, $3) \
                         ON CONFLICT DO NOTHING",
                    )
                    .bind(id)
                    .bind(author)
                    .bind(now_ms)
                    .execute(&mut *tx)
                    .await?;
                    if added.rows_affected() > 0 { LikeOutcome::Done } else { LikeOutcome::Unchanged }
                }
            };
            tx.commit().await?;
            Ok(outcome)
        })
    }

    fn unlike(&self, id: i64, author: &str) -> StoreFuture<'_, LikeOutcome> {
        let author = author.to_owned();
        Box::pin(async move {
            if self.fetch_comment(id).await?.is_none() {
                return Ok(LikeOutcome::NoComment);
            }
            let removed = sqlx::query("DELETE FROM likes WHERE comment_id = $1 AND author = $2")
                .bind(id)
                .bind(author)
                .execute(&self.pool)
                .await?;
            Ok(if removed.rows_affected() > 0 { LikeOutcome::Done } else { LikeOutcome::Unchanged })
        })
    }

    fn report(&self, id: i64, author: &str, now_ms: i64, hide_threshold: u32) -> StoreFuture<'_, ReportOutcome> {
        let author = author.to_owned();
        Box::pin(async move {
            let mut tx = self.pool.begin().await?;
            let exists: Option<i64> =
                sqlx::query_scalar("SELECT id FROM comments WHERE id = $1").bind(id).fetch_optional(&mut *tx).await?;
            if exists.is_none() {
                return Ok(ReportOutcome::NoComment);
            }
            let added = sqlx::query(
                "INSERT INTO reports (comment_id, author, created_ms) VALUES ($1, $2, $3) ON CONFLICT DO NOTHING",
            )
            .bind(id)
            .bind(author)
            .bind(now_ms)
            .execute(&mut *tx)
            .await?;
            let counted = added.rows_affected() > 0;
            if counted {
                sqlx::query(
                    "UPDATE comments SET reports = reports + 1, status = CASE WHEN reports + 1 >= $2 \
                     AND status = 'visible' THEN 'hidden' ELSE status END WHERE id = $1",
                )
                .bind(id)
                .bind(i64::from(hide_threshold))
                .execute(&mut *tx)
                .await?;
            }
            tx.commit().await?;
            let comment = self
                .fetch_comment(id)
                .await?
                .ok_or_else(|| ParticipationError::Database("the reported comment is gone".into()))?;
            Ok(if counted { ReportOutcome::Counted(comment) } else { ReportOutcome::Repeated(comment) })
        })
    }

    fn viewpoints(&self) -> StoreFuture<'_, Vec<StoredViewpoint>> {
        Box::pin(async move {
            let rows = sqlx::query("SELECT name, body, ordinal, updated_ms FROM viewpoints ORDER BY ordinal, name")
                .fetch_all(&self.pool)
                .await?;
            rows.iter()
                .map(|row| {
                    let body: String = row.try_get("body")?;
                    Ok(StoredViewpoint {
                        name: row.try_get("name")?,
                        body: serde_json::from_str(&body)
                            .map_err(|e| ParticipationError::Corrupt(format!("viewpoint body: {e}")))?,
                        ordinal: row.try_get("ordinal")?,
                        updated_ms: row.try_get("updated_ms")?,
                    })
                })
                .collect()
        })
    }

    fn put_viewpoint(&self, name: &str, body: serde_json::Value, now_ms: i64) -> StoreFuture<'_, bool> {
        let name = name.to_owned();
        Box::pin(async move {
            let body = body.to_string();
            let mut tx = self.pool.begin().await?;
            let updated = sqlx::query("UPDATE viewpoints SET body = $1, updated_ms = $2 WHERE name = $3")
                .bind(body.clone())
                .bind(now_ms)
                .bind(name.clone())
                .execute(&mut *tx)
                .await?;
            let created = updated.rows_affected() == 0;
            if created {
                sqlx::query(
                    "INSERT INTO viewpoints (name, body, ordinal, updated_ms) \
                     SELECT $1, $2, COALESCE(MAX(ordinal), 0) + 1, $3 FROM viewpoints",
                )
                .bind(name)
                .bind(body)
                .bind(now_ms)
                .execute(&mut *tx)
                .await?;
            }
            tx.commit().await?;
            Ok(created)
        })
    }

    fn delete_viewpoint(&self, name: &str) -> StoreFuture<'_, bool> {
        let name = name.to_owned();
        Box::pin(async move {
            let deleted = sqlx::query("DELETE FROM viewpoints WHERE name = $1").bind(name).execute(&self.pool).await?;
            Ok(deleted.rows_affected() > 0)
        })
    }

    fn add_meeting(&self, meeting: Meeting) -> StoreFuture<'_, bool> {
        Box::pin(async move {
            let added = sqlx::query(
                "INSERT INTO meetings (code, presenter, created_ms, closed_ms) VALUES ($1, $2, $3, $4) \
                 ON CONFLICT DO NOTHING",
            )
            .bind(meeting.code)
            .bind(meeting.presenter)
            .bind(meeting.created_ms)
            .bind(meeting.closed_ms)
            .execute(&self.pool)
            .await?;
            Ok(added.rows_affected() > 0)
        })
    }

    fn meeting(&self, code: &str) -> StoreFuture<'_, Option<Meeting>> {
        let code = code.to_owned();
        Box::pin(async move {
            let row = sqlx::query("SELECT code, presenter, created_ms, closed_ms FROM meetings WHERE code = $1")
                .bind(code)
                .fetch_optional(&self.pool)
                .await?;
            row.map(|row| {
                Ok(Meeting {
                    code: row.try_get("code")?,
                    presenter: row.try_get("presenter")?,
                    created_ms: row.try_get("created_ms")?,
                    closed_ms: row.try_get("closed_ms")?,
                })
            })
            .transpose()
        })
    }

    fn close_meeting(&self, code: &str, now_ms: i64) -> StoreFuture<'_, bool> {
        let code = code.to_owned();
        Box::pin(async move {
            let closed = sqlx::query("UPDATE meetings SET closed_ms = $1 WHERE code = $2 AND closed_ms IS NULL")
                .bind(now_ms)
                .bind(code)
                .execute(&self.pool)
                .await?;
            Ok(closed.rows_affected() > 0)
        })
    }
}

/// The test harness's PostgreSQL, shared with the integration tests.
#[cfg(test)]
#[path = "../../../../tests/common/postgres.rs"]
mod temp_postgres;

#[cfg(test)]
mod tests {
    use super::super::author_hash;
    use super::*;

    fn new_comment(text: &str, author: &str, status: CommentStatus, created_ms: i64) -> NewComment {
        NewComment {
            position: [10.5, -3.25, 101.0],
            lon_lat: [-105.3, 40.01],
            hit: Hit::Plant { layer: "planned".into(), index: 7 },
            camera: serde_json::json!({"position": [0.0, 0.0, 2.0], "yaw": 10.0}),
            text: text.into(),
            category: Some("idea".into()),
            created_ms,
            author: author_hash(author),
            status,
        }
    }

    /// Every store operation, against one database (SQLite and PostgreSQL below).
    async fn exercise(store: &dyn ParticipationStore) {
        let a = store.add_comment(new_comment("first", "alice", CommentStatus::Visible, 1000)).await.expect("add");
        let b = store.add_comment(new_comment("second", "bob", CommentStatus::Pending, 2000)).await.expect("add");
        assert_eq!((a.number, b.number), (1, 2));
        assert_eq!(a.hit, Hit::Plant { layer: "planned".into(), index: 7 });
        assert_eq!((a.position, a.lon_lat, a.text.as_str()), ([10.5, -3.25, 101.0], [-105.3, 40.01], "first"));
        assert_eq!(store.comment(a.id).await.expect("get"), Some(a.clone()));
        let public = store.comments(CommentFilter::public()).await.expect("list");
        assert_eq!(public.iter().map(|c| c.id).collect::<Vec<_>>(), vec![a.id]);
        let late = CommentFilter { since_ms: Some(1500), ..CommentFilter::default() };
        assert_eq!(store.comments(late).await.expect("list").len(), 1);
        let other = CommentFilter { category: Some("concern".into()), ..CommentFilter::default() };
        assert!(store.comments(other).await.expect("list").is_empty());

        let bob = author_hash("bob");
        assert_eq!(store.like(a.id, &bob, 3000).await.expect("like"), LikeOutcome::Done);
        assert_eq!(store.like(a.id, &bob, 3001).await.expect("like"), LikeOutcome::Unchanged);
        assert_eq!(store.like(a.id, &author_hash("alice"), 3002).await.expect("like"), LikeOutcome::OwnComment);
        assert_eq!(store.like(424242, &bob, 3003).await.expect("like"), LikeOutcome::NoComment);
        assert_eq!(store.comment(a.id).await.expect("get").map(|c| c.likes), Some(1));
        assert_eq!(store.unlike(a.id, &bob).await.expect("unlike"), LikeOutcome::Done);
        assert_eq!(store.unlike(a.id, &bob).await.expect("unlike"), LikeOutcome::Unchanged);

        let first = store.report(a.id, &bob, 4000, 2).await.expect("report");
        assert!(matches!(&first, ReportOutcome::Counted(c) if c.reports == 1 && c.status == CommentStatus::Visible));
        let again = store.report(a.id, &bob, 4001, 2).await.expect("report");
        assert!(matches!(&again, ReportOutcome::Repeated(c) if c.reports == 1));
        let second = store.report(a.id, &author_hash("carol"), 4002, 2).await.expect("report");
        assert!(matches!(&second, ReportOutcome::Counted(c) if c.reports == 2 && c.status == CommentStatus::Hidden));
        assert!(store.comments(CommentFilter::public()).await.expect("list").is_empty());

        let shown = store.set_status(b.id, CommentStatus::Visible).await.expect("status").expect("exists");
        assert_eq!(shown.status, CommentStatus::Visible);
        assert_eq!(store.set_status(424242, CommentStatus::Visible).await.expect("status"), None);
        store.like(b.id, &author_hash("alice"), 5000).await.expect("like");
        assert_eq!(store.delete_comment(b.id).await.expect("delete").map(|c| c.id), Some(b.id));
        assert_eq!(store.delete_comment(b.id).await.expect("delete"), None);
        let c = store.add_comment(new_comment("third", "carol", CommentStatus::Visible, 6000)).await.expect("add");
        assert_eq!(c.number, 3, "numbers are not reused");

        assert!(store.put_viewpoint("woods", serde_json::json!({"caption": "a"}), 1).await.expect("put"));
        assert!(store.put_viewpoint("hill", serde_json::json!({"caption": "b"}), 2).await.expect("put"));
        assert!(!store.put_viewpoint("woods", serde_json::json!({"caption": "c"}), 3).await.expect("put"));
        let viewpoints = store.viewpoints().await.expect("viewpoints");
        let names: Vec<_> = viewpoints.iter().map(|v| (v.name.as_str(), v.body["caption"].as_str())).collect();
        assert_eq!(names, vec![("woods", Some("c")), ("hill", Some("b"))]);
        assert!(store.delete_viewpoint("woods").await.expect("delete"));
        assert!(!store.delete_viewpoint("woods").await.expect("delete"));

        let meeting = Meeting { code: "K7Q2".into(), presenter: "p".into(), created_ms: 9, closed_ms: None };
        assert!(store.add_meeting(meeting.clone()).await.expect("meeting"));
        assert!(!store.add_meeting(meeting.clone()).await.expect("meeting"));
        assert_eq!(store.meeting("K7Q2").await.expect("meeting"), Some(meeting));
        assert!(store.close_meeting("K7Q2", 10).await.expect("close"));
        assert!(!store.close_meeting("K7Q2", 11).await.expect("close"));
        assert_eq!(store.meeting("K7Q2").await.expect("meeting").and_then(|m| m.closed_ms), Some(10));
        assert_eq!(store.meeting("NONE").await.expect("meeting"), None);
    }

    #[tokio::test]
    async fn sqlite_store_does_everything_and_keeps_it_across_reopening() {
        let dir = tempfile::tempdir().expect("temporary directory");
        let store = SqlStore::open_in(dir.path()).await.expect("open");
        exercise(&store).await;
        store.close().await;
        let reopened = SqlStore::open_in(dir.path()).await.expect("reopen");
        let texts: Vec<_> =
            reopened.comments(CommentFilter::default()).await.expect("list").into_iter().map(|c| c.text).collect();
        assert_eq!(texts, vec!["first", "third"]);
        let mode: String = sqlx::query_scalar("PRAGMA journal_mode").fetch_one(&reopened.pool).await.expect("pragma");
        assert_eq!(mode, "wal");
    }

    #[tokio::test]
    async fn postgres_store_runs_the_same_migrations_and_queries() {
        let Some(postgres) = super::temp_postgres::TempPostgres::start() else {
            eprintln!("PostgreSQL is not installed (scripts/setup installs it); skipped");
            return;
        };
        let store = SqlStore::open(&postgres.url()).await.expect("open");
        exercise(&store).await;
        store.close().await;
    }

    #[test]
    fn urls_are_redacted_and_paths_encoded() {
        assert_eq!(
            redacted("postgres://user:pw@db.example:5432/landsketch?sslmode=require"),
            "postgres://db.example:5432"
        );
        assert_eq!(sqlite_url(Path::new("/d/a?b#c%")), "sqlite:///d/a%3Fb%23c%25?mode=rwc");
    }
}
