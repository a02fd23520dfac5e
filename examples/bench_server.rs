//! Benchmark of `landsketch serve` on loopback: REST renders per second for a repeated (cached)
//! and for fresh views, and WebSocket control-to-frame latency (median, p95) and per-session
//! frame rates with 1 and more concurrent sessions, plus resident memory before, during and
//! after the sessions. Prints a Markdown report for BENCHMARKS.md.
//!
//! ```sh
//! cargo run --release --example bench_server -- --sessions 1,20 --seconds 30
//! ```

use anyhow::{Context, Result, bail};
use clap::Parser;
use futures_util::{SinkExt, StreamExt};
use landsketch::api::ws::FrameHeader;
use landsketch::api::{Server, ServerConfig};
use landsketch::bench::{percentile, rss_mib};
use landsketch::render::Gpu;
use landsketch::scene::Scene;
use std::net::SocketAddr;
use std::sync::Arc;
use std::time::{Duration, Instant};
use tokio_tungstenite::tungstenite::Message;

#[derive(Parser)]
struct Args {
    /// Scene file.
    #[arg(long, default_value = "data/boulder/scene.toml")]
    scene: std::path::PathBuf,
    /// Image width.
    #[arg(long, default_value_t = 1024)]
    width: u32,
    /// Image height.
    #[arg(long, default_value_t = 768)]
    height: u32,
    /// REST requests per measurement.
    #[arg(long, default_value_t = 20)]
    rest: u32,
    /// Concurrent WebSocket sessions per measurement, comma-separated.
    #[arg(long, value_delimiter = ',', default_value = "1,20")]
    sessions: Vec<usize>,
    /// Seconds each WebSocket measurement runs.
    #[arg(long, default_value_t = 30)]
    seconds: u64,
}

/// Renders per second of `count` sequential GETs produced by `url`.
async fn rest_rate(client: &reqwest::Client, count: u32, url: impl Fn(u32) -> String) -> Result<f64> {
    let started = Instant::now();
    for i in 0..count {
        let response = client.get(url(i)).send().await?;
        if !response.status().is_success() {
            bail!("GET {} answered {}", url(i), response.status());
        }
        response.bytes().await?;
    }
    Ok(f64::from(count) / started.elapsed().as_secs_f64())
}

/// One session moving its camera in a closed loop: send a move, wait for the frame that
/// reflects it, repeat. Returns the control-to-frame latencies in ms and the frame count.
async fn session(url: String, run_for: Duration, index: usize) -> Result<(Vec<f64>, u32)> {
    let (mut socket, _) = tokio_tungstenite::connect_async(&url).await?;
    let started = Instant::now();
    let (mut latencies, mut frames, mut seq) = (Vec::new(), 0u32, 0u32);
    let mut sent = Instant::now();
    let mut waiting = false;
    while started.elapsed() < run_for {
        if !waiting {
            let step = serde_json::json!({"type": "move", "yaw": 2.0 + index as f64 * 0.1, "forward": 0.5});
            socket.send(Message::text(step.to_string())).await?;
            seq += 1;
            sent = Instant::now();
            waiting = true;
        }
        let next =
            tokio::time::timeout(Duration::from_secs(120), socket.next()).await.context("no message in 120 s")?;
        match next {
            Some(Ok(Message::Binary(bytes))) => {
                frames += 1;
                let header = FrameHeader::decode(&bytes).context("bad frame header")?;
                if waiting && header.seq >= seq {
                    latencies.push(sent.elapsed().as_secs_f64() * 1e3);
                    waiting = false;
                }
            }
            Some(Ok(_)) => {}
            other => bail!("session {index} ended: {other:?}"),
        }
    }
    socket.close(None).await?;
    Ok((latencies, frames))
}

#[tokio::main]
async fn main() -> Result<()> {
    let args = Args::parse();
    let scene = Arc::new(Scene::load(&args.scene)?);
    let gpu = Arc::new(Gpu::new()?);
    let adapter = gpu.adapter_info.name.clone();
    let mut config = ServerConfig::try_parse_from(["serve", "--addr", "127.0.0.1:0", "--max-sessions", "256"])?;
    config.scene = args.scene.clone();
    config.data_dir = std::env::temp_dir().join("landsketch-bench");
    config.queue_depth = 1024;
    let server = Server::bind(config).await?;
    let addr: SocketAddr = server.local_addr()?;
    let (stop, stopped) = tokio::sync::oneshot::channel::<()>();
    let running = tokio::spawn(server.run_with(scene, gpu, async move {
        let _ = stopped.await;
    }));
    let client = reqwest::Client::new();
    let health = format!("http://{addr}/api/health");
    while client.get(&health).send().await.map(|r| r.status().as_u16()).unwrap_or(0) != 200 {
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    let (w, h) = (args.width, args.height);
    println!("# landsketch serve benchmark\n\nadapter: {adapter}; {w}×{h} JPEG unless noted\n");

    let view = |yaw: u32| format!("http://{addr}/api/render?yaw={yaw}&width={w}&height={h}&format=jpeg");
    let fresh = rest_rate(&client, args.rest, |i| view(i * 3 + 1)).await?;
    let cached = rest_rate(&client, args.rest, |_| view(1)).await?;
    println!(
        "| REST | renders/s |\n| --- | --- |\n| fresh views | {fresh:.2} |\n| repeated view (cache) | {cached:.1} |\n"
    );

    println!(
        "| sessions | frames/s per session (min–max) | control→frame median ms | p95 ms | RSS MiB before / during / after |"
    );
    println!("| --- | --- | --- | --- | --- |");
    for &count in &args.sessions {
        let before = rss_mib().unwrap_or(f64::NAN);
        let run_for = Duration::from_secs(args.seconds);
        let url = format!("ws://{addr}/api/ws?width={w}&height={h}&format=jpeg");
        let tasks: Vec<_> = (0..count).map(|i| tokio::spawn(session(url.clone(), run_for, i))).collect();
        tokio::time::sleep(run_for / 2).await;
        let during = rss_mib().unwrap_or(f64::NAN);
        let mut latencies = Vec::new();
        let mut rates = Vec::new();
        for task in tasks {
            let (l, frames) = task.await??;
            latencies.extend(l);
            rates.push(f64::from(frames) / run_for.as_secs_f64());
        }
        tokio::time::sleep(Duration::from_secs(1)).await;
        let after = rss_mib().unwrap_or(f64::NAN);
        latencies.sort_by(f64::total_cmp);
        rates.sort_by(f64::total_cmp);
        println!(
            "| {count} | {:.2}–{:.2} | {:.0} | {:.0} | {before:.0} / {during:.0} / {after:.0} |",
            rates.first().copied().unwrap_or(0.0),
            rates.last().copied().unwrap_or(0.0),
            percentile(&latencies, 0.5),
            percentile(&latencies, 0.95),
        );
    }
    let _ = stop.send(());
    running.await??;
    Ok(())
}
