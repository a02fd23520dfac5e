//! Benchmark of a meeting (presenter mode) on loopback: one presenter moving its camera
//! continuously (send a move, wait for its frame, repeat) and N followers receiving the
//! presenter's frames. Reports the frames each follower got against the presenter's, the
//! delay a follower gets a frame after the presenter (p50/p95), the renders the server did
//! (from `/metrics`: they must equal the presenter's frames) and resident memory. Prints a
//! Markdown report for BENCHMARKS.md.
//!
//! ```sh
//! cargo run --release --example bench_meeting -- --followers 100 --seconds 30
//! ```

use anyhow::{Context, Result, bail};
use clap::Parser;
use futures_util::{SinkExt, StreamExt};
use landsketch::api::ws::FrameHeader;
use landsketch::api::{Server, ServerConfig};
use landsketch::bench::{percentile, rss_mib};
use landsketch::render::Gpu;
use landsketch::scene::Scene;
use std::collections::HashMap;
use std::net::SocketAddr;
use std::sync::Arc;
use std::time::{Duration, Instant};
use tokio::sync::watch;
use tokio_tungstenite::tungstenite::Message;

#[derive(Parser)]
struct Args {
    /// Scene file.
    #[arg(long, default_value = "data/boulder/scene.toml")]
    scene: std::path::PathBuf,
    /// Presenter's image width.
    #[arg(long, default_value_t = 1024)]
    width: u32,
    /// Presenter's image height.
    #[arg(long, default_value_t = 768)]
    height: u32,
    /// Followers.
    #[arg(long, default_value_t = 100)]
    followers: usize,
    /// Seconds the presenter moves.
    #[arg(long, default_value_t = 30)]
    seconds: u64,
}

/// The sum of a metric's samples (all label sets).
async fn metric(client: &reqwest::Client, addr: SocketAddr, name: &str) -> Result<f64> {
    let text = client.get(format!("http://{addr}/metrics")).send().await?.text().await?;
    Ok(text
        .lines()
        .filter(|l| l.starts_with(name) && l[name.len()..].starts_with([' ', '{']))
        .filter_map(|l| l.rsplit(' ').next()?.parse::<f64>().ok())
        .sum())
}

type Socket = tokio_tungstenite::WebSocketStream<tokio_tungstenite::MaybeTlsStream<tokio::net::TcpStream>>;

/// The next binary frame's header; JSON messages are passed to `text`.
async fn next_frame(socket: &mut Socket, mut text: impl FnMut(&str)) -> Result<FrameHeader> {
    loop {
        match tokio::time::timeout(Duration::from_secs(120), socket.next()).await.context("no message in 120 s")? {
            Some(Ok(Message::Binary(bytes))) => return FrameHeader::decode(&bytes).context("bad frame header"),
            Some(Ok(Message::Text(t))) => text(t.as_str()),
            Some(Ok(_)) => {}
            other => bail!("the connection ended: {other:?}"),
        }
    }
}

/// A follower: joins, reports its first frame on `joined`, then records when each frame
/// arrived until `stop` turns true.
async fn follower(
    url: String,
    joined: tokio::sync::mpsc::Sender<()>,
    mut stop: watch::Receiver<bool>,
) -> Result<HashMap<u32, Instant>> {
    let (mut socket, _) = tokio_tungstenite::connect_async(&url).await?;
    next_frame(&mut socket, |_| {}).await?;
    joined.send(()).await?;
    let mut arrived = HashMap::new();
    loop {
        tokio::select! {
            frame = next_frame(&mut socket, |_| {}) => { arrived.insert(frame?.frame_id, Instant::now()); }
            _ = stop.wait_for(|s| *s) => break,
        }
    }
    socket.close(None).await?;
    Ok(arrived)
}

#[tokio::main]
async fn main() -> Result<()> {
    let args = Args::parse();
    let scene = Arc::new(Scene::load(&args.scene)?);
    let gpu = Arc::new(Gpu::new()?);
    let adapter = gpu.adapter_info.name.clone();
    // Followers take no rendering slot (`--max-sessions`); their own limit fits the audience.
    let followers = args.followers.max(1000).to_string();
    let mut config = ServerConfig::try_parse_from(["serve", "--addr", "127.0.0.1:0", "--max-followers", &followers])?;
    config.scene = args.scene.clone();
    config.data_dir = std::env::temp_dir().join("landsketch-bench-meeting");
    let server = Server::bind(config).await?;
    let addr: SocketAddr = server.local_addr()?;
    let (stop_server, stopped) = tokio::sync::oneshot::channel::<()>();
    let running = tokio::spawn(server.run_with(scene, gpu, async move {
        let _ = stopped.await;
    }));
    let client = reqwest::Client::new();
    while client.get(format!("http://{addr}/api/health")).send().await.map(|r| r.status().as_u16()).unwrap_or(0) != 200
    {
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    let (w, h) = (args.width, args.height);
    let rss_before = rss_mib().unwrap_or(f64::NAN);

    // The presenter opens the meeting.
    let (mut presenter, _) =
        tokio_tungstenite::connect_async(format!("ws://{addr}/api/ws?width={w}&height={h}&format=jpeg")).await?;
    next_frame(&mut presenter, |_| {}).await?;
    presenter.send(Message::text(r#"{"type": "open_meeting", "caption": "benchmark"}"#)).await?;
    let mut code = None;
    while code.is_none() {
        next_frame(&mut presenter, |t| {
            if let Ok(v) = serde_json::from_str::<serde_json::Value>(t)
                && v["type"] == "meeting"
            {
                code = v["code"].as_str().map(str::to_owned);
            }
        })
        .await?;
    }
    let code = code.context("no meeting code")?;

    // The followers join and take the opening frame.
    let (joined_tx, mut joined) = tokio::sync::mpsc::channel(args.followers);
    let (stop_tx, stop_rx) = watch::channel(false);
    let url = format!("ws://{addr}/api/ws?meeting={code}");
    let tasks: Vec<_> =
        (0..args.followers).map(|_| tokio::spawn(follower(url.clone(), joined_tx.clone(), stop_rx.clone()))).collect();
    for _ in 0..args.followers {
        joined.recv().await.context("a follower failed to join")?;
    }
    let renders_before = metric(&client, addr, "landsketch_render_seconds_count").await?;

    // The presenter moves in a closed loop, then rests until its still.
    let mut presented: HashMap<u32, Instant> = HashMap::new();
    let started = Instant::now();
    let run_for = Duration::from_secs(args.seconds);
    let mut rss_during = 0.0;
    let mut seq = 0u32;
    while started.elapsed() < run_for {
        presenter.send(Message::text(r#"{"type": "move", "yaw": 1.5, "forward": 1.0}"#)).await?;
        seq += 1;
        loop {
            let header = next_frame(&mut presenter, |_| {}).await?;
            presented.insert(header.frame_id, Instant::now());
            if header.seq >= seq {
                break;
            }
        }
        if rss_during == 0.0 && started.elapsed() > run_for / 2 {
            rss_during = rss_mib().unwrap_or(f64::NAN);
        }
    }
    let moving_frames = presented.len();
    loop {
        let header = next_frame(&mut presenter, |_| {}).await?;
        presented.insert(header.frame_id, Instant::now());
        if header.still {
            break;
        }
    }
    let elapsed = started.elapsed().as_secs_f64();
    // Followers take the last frames, then stop.
    tokio::time::sleep(Duration::from_secs(2)).await;
    let renders = metric(&client, addr, "landsketch_render_seconds_count").await? - renders_before;
    let meeting_renders = metric(&client, addr, "landsketch_meeting_renders_total").await?;
    stop_tx.send_replace(true);
    let mut shares = Vec::new();
    let mut delays = Vec::new();
    for task in tasks {
        let arrived = task.await??;
        let mut got = 0usize;
        for (id, presenter_at) in &presented {
            if let Some(at) = arrived.get(id) {
                got += 1;
                let delay = if at >= presenter_at {
                    at.duration_since(*presenter_at).as_secs_f64()
                } else {
                    -presenter_at.duration_since(*at).as_secs_f64()
                };
                delays.push(delay * 1e3);
            }
        }
        shares.push(got as f64 / presented.len() as f64);
    }
    presenter.close(None).await?;
    tokio::time::sleep(Duration::from_secs(1)).await;
    let rss_after = rss_mib().unwrap_or(f64::NAN);
    shares.sort_by(f64::total_cmp);
    delays.sort_by(f64::total_cmp);
    let frames = presented.len();
    println!("# landsketch meeting benchmark\n");
    println!(
        "adapter: {adapter}; presenter {w}×{h} JPEG (moving frames at --interactive-scale), {} followers, {elapsed:.1} s\n",
        args.followers
    );
    println!("| measure | value |\n| --- | --- |");
    println!(
        "| presenter frames (moving + final still) | {frames} ({moving_frames} + {}), {:.2}/s |",
        frames - moving_frames,
        frames as f64 / elapsed
    );
    println!("| renders during the run (`landsketch_render_seconds_count`) | {renders:.0} |");
    println!("| renders for the meeting (`landsketch_meeting_renders_total`, since opening) | {meeting_renders:.0} |");
    println!(
        "| frames per follower / presenter frames: min, median, max | {:.1} %, {:.1} %, {:.1} % |",
        shares.first().copied().unwrap_or(0.0) * 100.0,
        percentile(&shares, 0.5) * 100.0,
        shares.last().copied().unwrap_or(0.0) * 100.0
    );
    println!(
        "| followers with ≥ 90 % of the frames | {} of {} |",
        shares.iter().filter(|s| **s >= 0.9).count(),
        shares.len()
    );
    println!(
        "| follower delay after the presenter, p50 / p95 / max | {:.1} / {:.1} / {:.1} ms |",
        percentile(&delays, 0.5),
        percentile(&delays, 0.95),
        delays.last().copied().unwrap_or(f64::NAN)
    );
    println!(
        "| RSS (server and clients) before / during / after | {rss_before:.0} / {rss_during:.0} / {rss_after:.0} MiB |"
    );
    let _ = stop_server.send(());
    running.await??;
    Ok(())
}
