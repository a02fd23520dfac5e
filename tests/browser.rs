//! End-to-end tests of the browser UI (issues #8, #15): starts a real server with the sample
//! scene, an empty layer store and an admin token (so the planner's login and authorised
//! uploads are exercised), then runs `node tests/browser/e2e.mjs <base-url>`, which drives
//! headless Chromium with Playwright (see that file for the checks). Needs Node.js, Debian's
//! `chromium` (or `$CHROMIUM`) and `npm ci` in `tests/browser/` — `scripts/setup` installs all
//! three. `LANDSKETCH_UI_SCREENSHOTS=DIR` also writes the README's screenshots to DIR.

mod common;

use common::server::TestServer;
use std::path::Path;
use std::process::Command;

/// Fails with what to install when a prerequisite is missing.
fn require_tools() -> String {
    let chromium = std::env::var("CHROMIUM").unwrap_or_else(|_| "/usr/bin/chromium".into());
    assert!(
        Path::new(&chromium).is_file(),
        "{chromium} not found: the browser tests need Chromium (`apt-get install chromium`, or set CHROMIUM); \
         scripts/setup installs it"
    );
    assert!(
        Path::new("tests/browser/node_modules/playwright-core").is_dir(),
        "tests/browser/node_modules is missing: run `npm ci` in tests/browser (scripts/setup does)"
    );
    let node = Command::new("node").arg("--version").output();
    assert!(
        node.as_ref().is_ok_and(|o| o.status.success()),
        "node not found: the browser tests need Node.js 18 or later (`apt-get install nodejs`); scripts/setup installs it"
    );
    chromium
}

/// The planner's token of the test server.
const ADMIN_TOKEN: &str = "e2e-planner-token";

#[test]
fn browser_ui_end_to_end() {
    let chromium = require_tools();
    let data = tempfile::tempdir().expect("temp dir");
    let server = TestServer::start(data.path(), |config| config.admin_token = Some(ADMIN_TOKEN.into()));
    let mut command = Command::new("node");
    command
        .arg("tests/browser/e2e.mjs")
        .arg(server.url(""))
        .env("CHROMIUM", chromium)
        .env("LANDSKETCH_ADMIN_TOKEN", ADMIN_TOKEN);
    if let Ok(dir) = std::env::var("LANDSKETCH_UI_SCREENSHOTS") {
        command.arg("--screenshots").arg(dir);
    }
    let output = command.output().expect("run node");
    let stdout = String::from_utf8_lossy(&output.stdout);
    let stderr = String::from_utf8_lossy(&output.stderr);
    println!("{stdout}");
    eprintln!("{stderr}");
    assert!(output.status.success(), "the browser tests failed ({}); their output is above", output.status);
}
