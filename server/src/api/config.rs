//! Configuration of `landsketch serve`: every flag has an environment variable as fallback.

use clap::Parser;
use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::time::Duration;

/// Flags and environment of `landsketch serve` (see README, "Server").
#[derive(Debug, Clone, Parser)]
#[command(name = "landsketch serve")]
pub struct ServerConfig {
    /// Scene file to serve.
    #[arg(long, env = "LANDSKETCH_SCENE", default_value = crate::scene::SAMPLE_SCENE)]
    pub scene: PathBuf,
    /// Address to listen on (port 0 picks a free port).
    #[arg(long, env = "LANDSKETCH_ADDR", default_value = "127.0.0.1:8080")]
    pub addr: SocketAddr,
    /// Directory for server data (uploaded layers); created when missing.
    #[arg(long, env = "LANDSKETCH_DATA_DIR", default_value = "landsketch-data")]
    pub data_dir: PathBuf,
    /// Database of the participation store (comments, likes, viewpoints, meetings):
    /// `postgres://user:password@host/db` for several replicas (which then share layers and
    /// art maps too), `sqlite://path`; default the SQLite file `participation.sqlite` in the
    /// data directory.
    #[arg(long, env = "LANDSKETCH_DATABASE_URL", hide_env_values = true)]
    pub database_url: Option<String>,
    /// Directory of the preprocessing cache (HLPs, baked billboards), so a restart with the
    /// same scene skips preprocessing; default `<data-dir>/cache`.
    #[arg(long, env = "LANDSKETCH_CACHE_DIR")]
    pub cache_dir: Option<PathBuf>,
    /// Time the passes of every n-th frame for `/metrics` (`landsketch_render_pass_seconds`);
    /// a sampled frame waits for the GPU after each pass, so it is slightly slower. 0: never.
    #[arg(long, env = "LANDSKETCH_PROFILE_EVERY", default_value_t = 10)]
    pub profile_every: u32,
    /// Directory of the browser UI, served at `/` (index.html, ES modules, CSS).
    #[arg(long, env = "LANDSKETCH_WEB_DIR", default_value = "web")]
    pub web_dir: PathBuf,
    /// Token that write endpoints require as `Authorization: Bearer <token>`; without one,
    /// writes are accepted from loopback clients only. Prefer `--admin-token-file` or the
    /// environment: a token given as flag is visible in the process list (a warning says so).
    #[arg(long, env = "LANDSKETCH_ADMIN_TOKEN", hide_env_values = true)]
    pub admin_token: Option<String>,
    /// File holding the admin token (surrounding white space is ignored); read at start-up,
    /// an empty or unreadable file stops the server.
    #[arg(long, env = "LANDSKETCH_ADMIN_TOKEN_FILE", conflicts_with = "admin_token")]
    pub admin_token_file: Option<PathBuf>,
    /// Password that lets a client open a meeting (presenter mode) without the admin token,
    /// given as `password` in `POST /api/meetings` or the `open_meeting` message. Prefer
    /// `--meeting-password-file` or the environment over the flag.
    #[arg(long, env = "LANDSKETCH_MEETING_PASSWORD", hide_env_values = true)]
    pub meeting_password: Option<String>,
    /// File holding the meeting password (surrounding white space is ignored); read at
    /// start-up, an empty or unreadable file stops the server.
    #[arg(long, env = "LANDSKETCH_MEETING_PASSWORD_FILE", conflicts_with = "meeting_password")]
    pub meeting_password_file: Option<PathBuf>,
    /// Origins allowed to call the API from a browser (CORS), comma-separated, or `*`;
    /// CORS is off when empty.
    #[arg(long, env = "LANDSKETCH_CORS_ORIGINS", value_delimiter = ',')]
    pub cors_origins: Vec<String>,
    /// Largest image width in pixels.
    #[arg(long, env = "LANDSKETCH_MAX_WIDTH", default_value_t = 2048, value_parser = clap::value_parser!(u32).range(1..=8192))]
    pub max_width: u32,
    /// Largest image height in pixels.
    #[arg(long, env = "LANDSKETCH_MAX_HEIGHT", default_value_t = 2048, value_parser = clap::value_parser!(u32).range(1..=8192))]
    pub max_height: u32,
    /// REST renders that may wait for the renderer; more get 503 with Retry-After.
    #[arg(long, env = "LANDSKETCH_QUEUE_DEPTH", default_value_t = 32, value_parser = clap::value_parser!(u32).range(1..=4096))]
    pub queue_depth: u32,
    /// Bytes of encoded images kept in the render cache (0 disables it).
    #[arg(long, env = "LANDSKETCH_CACHE_BYTES", default_value_t = 64 << 20)]
    pub cache_bytes: usize,
    /// Largest request body in bytes.
    #[arg(long, env = "LANDSKETCH_BODY_LIMIT", default_value_t = 1 << 20)]
    pub body_limit: usize,
    /// Largest layer upload (`POST /api/layers` body) in bytes; larger uploads get 413.
    #[arg(long, env = "LANDSKETCH_MAX_UPLOAD", default_value_t = 64 << 20)]
    pub max_upload: usize,
    /// Seconds a client may take to send a request's headers, and to start the next request
    /// on a kept-alive connection; then the connection is closed.
    #[arg(long, env = "LANDSKETCH_HEADER_TIMEOUT", default_value_t = 10, value_parser = clap::value_parser!(u64).range(1..=3600))]
    pub header_timeout_s: u64,
    /// Seconds a client may take to send a request body once its headers are in (a slow
    /// upload); then the request fails and the connection is closed.
    #[arg(long, env = "LANDSKETCH_BODY_TIMEOUT", default_value_t = 60, value_parser = clap::value_parser!(u64).range(1..=86400))]
    pub body_timeout_s: u64,
    /// Uploads (layer files, art-map PNGs) decoded at the same time; more wait their turn.
    #[arg(long, env = "LANDSKETCH_UPLOAD_DECODES", default_value_t = 2, value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(1..=64))]
    pub upload_decodes: usize,
    /// Largest WebSocket message a client may send, in bytes.
    #[arg(long, env = "LANDSKETCH_WS_MAX_MESSAGE", default_value_t = 64 << 10)]
    pub ws_max_message: usize,
    /// Concurrent WebSocket sessions rendering their own view; more are refused with 503.
    #[arg(long, env = "LANDSKETCH_MAX_SESSIONS", default_value_t = 64)]
    pub max_sessions: usize,
    /// Concurrent WebSocket sessions following a meeting (they render nothing: the presenter's
    /// frames are shared); more are refused with 503.
    #[arg(long, env = "LANDSKETCH_MAX_FOLLOWERS", default_value_t = 1000)]
    pub max_followers: usize,
    /// Seconds without a client message after which a WebSocket session is closed.
    #[arg(long, env = "LANDSKETCH_IDLE_TIMEOUT", default_value_t = 300)]
    pub idle_timeout_s: u64,
    /// Seconds a WebSocket client may take to accept a message; a client that does not read
    /// for that long is disconnected (its session slot is freed).
    #[arg(long, env = "LANDSKETCH_WS_SEND_TIMEOUT", default_value_t = 10, value_parser = clap::value_parser!(u64).range(1..=3600))]
    pub ws_send_timeout_s: u64,
    /// Kernel send buffer of each connection, in bytes (0: the system's own, which grows to
    /// 4 MiB on Linux): bounds what a client that does not read holds, and lets a meeting
    /// follower that falls behind skip to the newest frame sooner.
    #[arg(long, env = "LANDSKETCH_SEND_BUFFER_BYTES", default_value_t = 1 << 20)]
    pub send_buffer_bytes: usize,
    /// Milliseconds of rest after the last control before a session gets its full-quality still.
    #[arg(long, env = "LANDSKETCH_STILL_DELAY_MS", default_value_t = 150)]
    pub still_delay_ms: u64,
    /// Frames per second a session gets at most while it moves.
    #[arg(long, env = "LANDSKETCH_MAX_FPS", default_value_t = 30, value_parser = clap::value_parser!(u32).range(1..=240))]
    pub max_fps: u32,
    /// Image size factor for frames rendered while the view moves (0.1..=1).
    #[arg(long, env = "LANDSKETCH_INTERACTIVE_SCALE", default_value_t = 0.5, value_parser = parse_scale)]
    pub interactive_scale: f32,
    /// JPEG quality of frames rendered while the view moves.
    #[arg(long, env = "LANDSKETCH_INTERACTIVE_QUALITY", default_value_t = 50, value_parser = clap::value_parser!(u8).range(1..=100))]
    pub interactive_quality: u8,
}

/// Why a secret file (`--admin-token-file`, `--meeting-password-file`) cannot be used.
#[derive(Debug, thiserror::Error)]
pub enum TokenFileError {
    /// The file cannot be read (missing, unreadable, not UTF-8).
    #[error("cannot read the secret file {path}: {source}")]
    Read { path: PathBuf, source: std::io::Error },
    /// The file holds nothing but white space.
    #[error("the secret file {path} is empty")]
    Empty { path: PathBuf },
}

/// Reads a secret (the admin token, the meeting password) from `path`: the file's text without surrounding white space (a
/// trailing newline is usual); an unreadable file or one without a token is an error naming it.
pub fn read_token_file(path: &Path) -> Result<String, TokenFileError> {
    let text =
        std::fs::read_to_string(path).map_err(|source| TokenFileError::Read { path: path.to_owned(), source })?;
    match text.trim() {
        "" => Err(TokenFileError::Empty { path: path.to_owned() }),
        token => Ok(token.to_owned()),
    }
}

/// Whether the command line `args` pass the admin token as `--admin-token` flag, where every
/// user of the machine can read it in the process list.
pub fn admin_token_on_command_line<I, S>(args: I) -> bool
where
    I: IntoIterator<Item = S>,
    S: AsRef<std::ffi::OsStr>,
{
    args.into_iter()
        .map(|arg| arg.as_ref().to_string_lossy().into_owned())
        .take_while(|arg| arg != "--")
        .any(|arg| arg == "--admin-token" || arg.starts_with("--admin-token="))
}

impl ServerConfig {
    /// Reads `--admin-token-file` and `--meeting-password-file`, when given, into
    /// `admin_token` and `meeting_password`.
    pub fn resolve_admin_token(&mut self) -> Result<(), TokenFileError> {
        if let Some(path) = &self.admin_token_file {
            self.admin_token = Some(read_token_file(path)?);
        }
        if let Some(path) = &self.meeting_password_file {
            self.meeting_password = Some(read_token_file(path)?);
        }
        Ok(())
    }

    /// Renderer options: the preprocessing cache in `cache_dir` (or `<data-dir>/cache`).
    pub fn render_options(&self) -> std::io::Result<crate::render::RenderOptions> {
        let dir = self.cache_dir.clone().unwrap_or_else(|| self.data_dir.join("cache"));
        let cache = crate::prep::cache::DiskCache::open(dir)?;
        Ok(crate::render::RenderOptions {
            cache: Some(std::sync::Arc::new(cache)),
            profile_every: self.profile_every,
            ..Default::default()
        })
    }

    /// Idle timeout of WebSocket sessions.
    pub fn idle_timeout(&self) -> Duration {
        Duration::from_secs(self.idle_timeout_s)
    }

    /// `--header-timeout-s` as a duration.
    pub fn header_timeout(&self) -> Duration {
        Duration::from_secs(self.header_timeout_s)
    }

    /// `--body-timeout-s` as a duration.
    pub fn body_timeout(&self) -> Duration {
        Duration::from_secs(self.body_timeout_s)
    }

    /// `--send-buffer-bytes`, `None` for the system's own.
    pub fn send_buffer(&self) -> Option<usize> {
        (self.send_buffer_bytes > 0).then_some(self.send_buffer_bytes)
    }

    /// `--ws-send-timeout-s` as a duration.
    pub fn ws_send_timeout(&self) -> Duration {
        Duration::from_secs(self.ws_send_timeout_s)
    }

    /// Rest after the last control before the still frame.
    pub fn still_delay(&self) -> Duration {
        Duration::from_millis(self.still_delay_ms)
    }

    /// Shortest interval between two frames of one session.
    pub fn frame_interval(&self) -> Duration {
        Duration::from_secs(1) / self.max_fps
    }
}

fn parse_scale(text: &str) -> Result<f32, String> {
    match text.parse::<f32>() {
        Ok(scale) if (0.1..=1.0).contains(&scale) => Ok(scale),
        _ => Err(format!("expected a number within 0.1..=1, got {text:?}")),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_token_file_is_read_trimmed() {
        let dir = tempfile::tempdir().expect("temporary directory");
        let path = dir.path().join("token");
        std::fs::write(&path, "  s3cret\n").expect("write");
        assert_eq!(read_token_file(&path).expect("token"), "s3cret");
        let mut config = ServerConfig::try_parse_from(["serve", "--admin-token-file", path.to_str().expect("UTF-8")])
            .expect("flags");
        config.resolve_admin_token().expect("token");
        assert_eq!(config.admin_token.as_deref(), Some("s3cret"));
    }

    #[test]
    fn an_empty_or_missing_token_file_is_an_error_naming_it() {
        let dir = tempfile::tempdir().expect("temporary directory");
        let empty = dir.path().join("empty");
        std::fs::write(&empty, " \n\t").expect("write");
        let error = read_token_file(&empty).expect_err("empty");
        assert!(matches!(error, TokenFileError::Empty { .. }));
        assert!(error.to_string().contains(&empty.display().to_string()), "{error}");
        let missing = dir.path().join("missing");
        let error = read_token_file(&missing).expect_err("missing");
        assert!(matches!(error, TokenFileError::Read { .. }));
        assert!(error.to_string().contains(&missing.display().to_string()), "{error}");
    }

    #[test]
    fn a_token_flag_is_noticed() {
        assert!(admin_token_on_command_line(["landsketch", "serve", "--admin-token", "x"]));
        assert!(admin_token_on_command_line(["landsketch", "serve", "--admin-token=x"]));
        assert!(!admin_token_on_command_line(["landsketch", "serve", "--admin-token-file", "f"]));
        assert!(!admin_token_on_command_line(["landsketch", "serve", "--admin-token-file=f"]));
        assert!(!admin_token_on_command_line(["landsketch", "serve", "--", "--admin-token"]));
    }

    #[test]
    fn the_token_and_its_file_exclude_each_other() {
        let both = ServerConfig::try_parse_from(["serve", "--admin-token", "x", "--admin-token-file", "f"]);
        assert!(both.is_err());
    }
}
