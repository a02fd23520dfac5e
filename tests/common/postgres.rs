//! A throw-away PostgreSQL server for tests (Debian's `postgresql` package, installed by
//! `scripts/setup`): `initdb` in a temporary directory, the server on a Unix socket there
//! (no TCP port), stopped when dropped. Used by the integration tests (`tests/replicas.rs`)
//! and by the participation store's unit tests.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

/// The running server and its directory.
pub struct TempPostgres {
    dir: tempfile::TempDir,
    server: Child,
}

impl TempPostgres {
    /// The directory of the server binaries: Debian keeps them in
    /// `/usr/lib/postgresql/<major>/bin` (the newest is taken); an `initdb` in
    /// `/usr/local/bin` (or a link there) first.
    fn bin() -> Option<PathBuf> {
        if let Ok(initdb) = std::fs::canonicalize("/usr/local/bin/initdb") {
            return initdb.parent().map(Path::to_path_buf);
        }
        let debian = std::fs::read_dir("/usr/lib/postgresql").into_iter().flatten().flatten().map(|e| e.path());
        let mut majors: Vec<_> = debian.filter(|p| p.join("bin/initdb").exists()).collect();
        majors.sort_by_key(|p| p.file_name().and_then(|n| n.to_str()?.parse::<u32>().ok()));
        majors.pop().map(|p| p.join("bin"))
    }

    /// Runs `program` of the PostgreSQL binaries as the `postgres` user when this is root
    /// (PostgreSQL refuses to run as root).
    fn command(bin: &Path, program: &str) -> Command {
        let path = bin.join(program).to_string_lossy().into_owned();
        let root = Command::new("id").arg("-u").output().is_ok_and(|o| o.stdout == b"0\n");
        if root {
            let mut command = Command::new("setpriv");
            command.args(["--reuid=postgres", "--regid=postgres", "--init-groups", "--", &path]);
            command
        } else {
            Command::new(path)
        }
    }

    /// Starts a server and waits until it accepts connections; `None` when PostgreSQL is not
    /// installed.
    pub fn start() -> Option<TempPostgres> {
        let bin = Self::bin()?;
        let dir = tempfile::tempdir().expect("temporary directory");
        if let Ok(user) = Command::new("id").args(["-u", "postgres"]).output()
            && let Ok(uid) = String::from_utf8_lossy(&user.stdout).trim().parse::<u32>()
        {
            std::os::unix::fs::chown(dir.path(), Some(uid), None).expect("hand the directory to postgres");
        }
        let data = dir.path().join("data");
        let initdb = Self::command(&bin, "initdb")
            .args(["-A", "trust", "-U", "landsketch", "-D"])
            .arg(&data)
            .stdout(Stdio::null())
            .status()
            .expect("initdb");
        assert!(initdb.success(), "initdb failed");
        let server = Self::command(&bin, "postgres")
            .arg("-D")
            .arg(&data)
            .arg("-k")
            .arg(dir.path())
            .args(["-c", "listen_addresses="])
            .stderr(Stdio::null())
            .spawn()
            .expect("postgres");
        let postgres = TempPostgres { dir, server };
        let deadline = Instant::now() + Duration::from_secs(30);
        loop {
            let ready = Command::new(bin.join("pg_isready"))
                .args(["-q", "-U", "landsketch", "-d", "postgres", "-h"])
                .arg(postgres.dir.path())
                .status()
                .is_ok_and(|s| s.success());
            if ready {
                return Some(postgres);
            }
            assert!(Instant::now() < deadline, "PostgreSQL did not accept connections within 30 s");
            std::thread::sleep(Duration::from_millis(50));
        }
    }

    /// The database URL (user `landsketch`, database `postgres`, the socket directory as host).
    pub fn url(&self) -> String {
        format!("postgres://landsketch@localhost/postgres?host={}", self.dir.path().display())
    }
}

impl Drop for TempPostgres {
    fn drop(&mut self) {
        // SIGINT: PostgreSQL's fast shutdown (the server runs as another user, so signal it
        // with kill(1) rather than Child::kill's SIGKILL).
        let _ = Command::new("kill").args(["-INT", &self.server.id().to_string()]).status();
        let _ = self.server.wait();
    }
}
