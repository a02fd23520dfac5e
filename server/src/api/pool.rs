//! The render queue: one worker thread owns the [`Renderer`] and takes jobs round-robin from
//! lanes with pending work — one lane per WebSocket session (holding at most one job, which
//! newer controls replace until the worker starts it) and one FIFO lane for REST renders
//! (bounded; a full lane refuses new jobs). Finished images are encoded on tokio's blocking
//! pool so that encoding overlaps the next render. A REST job may instead ask what one pixel
//! shows ([`RenderPool::pick`]: its depth and object id, for pinning comments).

use super::metrics::{KindLabels, Metrics};
use super::view::ViewRequest;
use crate::render::art_textures::{ArtKind, ArtMap, ArtMapSet};
use crate::render::renderer::ViewState;
use crate::render::{FrameRequest, Readback};
use crate::render::{Gpu, RenderError, RenderOptions, Renderer};
use crate::scene::Scene;
use crate::store::Store;
use crate::store::request::LayerCache;
use axum::body::Bytes;
use std::collections::{HashMap, VecDeque};
use std::panic::AssertUnwindSafe;
use std::sync::atomic::{AtomicU32, Ordering};
use std::sync::{Arc, Condvar, Mutex, MutexGuard, PoisonError};
use std::time::Instant;
use tokio::runtime::Handle;
use tokio::sync::oneshot;

/// What a frame is rendered for (a metrics label and part of the WebSocket frame header).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FrameKind {
    /// A REST render.
    Rest,
    /// A WebSocket frame while the view moves (reduced size and quality).
    Interactive,
    /// A WebSocket frame of a view at rest (full size and quality).
    Still,
}

impl FrameKind {
    /// The metrics label of this kind.
    pub fn label(self) -> KindLabels {
        let kind = match self {
            FrameKind::Rest => "rest",
            FrameKind::Interactive => "interactive",
            FrameKind::Still => "still",
        };
        KindLabels { kind }
    }
}

/// Errors of the render queue.
#[derive(Debug, thiserror::Error)]
pub enum PoolError {
    /// The REST lane holds `depth` renders already.
    #[error("the render queue is full ({depth} renders waiting)")]
    Full { depth: usize, retry_after_s: u32 },
    /// The pool has been closed for shutdown.
    #[error("the renderer is shutting down")]
    Closed,
    /// The renderer failed.
    #[error(transparent)]
    Render(#[from] RenderError),
    /// Encoding the image failed.
    #[error("encoding the image failed: {0}")]
    Encode(#[from] image::ImageError),
    /// The renderer panicked; the worker goes on with the next job.
    #[error("the renderer panicked")]
    Panicked,
    /// The worker dropped the job without an answer (the job was replaced or the pool stopped).
    #[error("the render was cancelled")]
    Cancelled,
    /// A picked pixel lies outside the rendered image.
    #[error("pixel {x},{y} is outside the rendered image")]
    OutsideImage { x: u32, y: u32 },
}

/// What one pixel of a rendered view shows ([`RenderPool::pick`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pick {
    /// Linear depth along the view axis in metres ([`crate::render::gbuffer::BACKGROUND_DEPTH`]
    /// on the sky).
    pub depth: f32,
    /// The object id ([`crate::render::gbuffer::object_id`]; 0 on the sky).
    pub object_id: u32,
}

/// Where the answer of a pick arrives.
pub type PickReceiver = oneshot::Receiver<Result<Pick, PoolError>>;

/// An encoded frame.
#[derive(Debug, Clone)]
pub struct Frame {
    /// PNG or JPEG bytes.
    pub bytes: Bytes,
    /// Milliseconds the renderer spent on the frame.
    pub render_ms: f32,
}

/// Where the answer of a job arrives.
pub type FrameReceiver = oneshot::Receiver<Result<Frame, PoolError>>;

/// Who waits for a job, and for what.
enum Reply {
    /// The encoded image.
    Frame(oneshot::Sender<Result<Frame, PoolError>>),
    /// What the pixel shows.
    Pick { pixel: [u32; 2], reply: oneshot::Sender<Result<Pick, PoolError>> },
}

impl Reply {
    fn is_closed(&self) -> bool {
        match self {
            Reply::Frame(reply) => reply.is_closed(),
            Reply::Pick { reply, .. } => reply.is_closed(),
        }
    }
}

struct Job {
    view: ViewRequest,
    kind: FrameKind,
    /// The WebSocket session the job belongs to; its frames continue one animated view.
    session: Option<u64>,
    reply: Reply,
}

impl Job {
    fn new(view: ViewRequest, kind: FrameKind, session: Option<u64>) -> (Job, FrameReceiver) {
        let (reply, receiver) = oneshot::channel();
        (Job { view, kind, session, reply: Reply::Frame(reply) }, receiver)
    }
}

/// A change of the renderer's art maps (thesis 8.2.5), applied by the worker between frames.
#[derive(Debug, Clone)]
pub enum ArtChange {
    /// Replaces map `index` of the map's kind, or adds it when `index` is the count.
    Set { index: usize, map: ArtMap },
    /// Removes map `index` of `kind`, which must be the last one.
    Remove { kind: ArtKind, index: usize },
}

/// Where the answer to an art-map change arrives: the art maps after the change.
pub type ArtReceiver = oneshot::Receiver<Result<ArtMapSet, PoolError>>;

struct ArtJob {
    change: ArtChange,
    reply: oneshot::Sender<Result<ArtMapSet, PoolError>>,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Lane {
    Rest,
    Session(u64),
}

#[derive(Default)]
struct Queue {
    /// Lanes with pending work in round-robin order; a lane is listed once at most.
    ready: VecDeque<Lane>,
    rest: VecDeque<Job>,
    sessions: HashMap<u64, Job>,
    /// Sessions that ended since the worker last looked; their view states are dropped.
    left: Vec<u64>,
    /// Art-map changes, applied before the next frame.
    art: VecDeque<ArtJob>,
    next_session: u64,
    closed: bool,
}

impl Queue {
    fn depth(&self) -> usize {
        self.rest.len() + self.sessions.len()
    }

    fn pop(&mut self) -> Option<Job> {
        while let Some(lane) = self.ready.pop_front() {
            let job = match lane {
                Lane::Rest => {
                    let job = self.rest.pop_front();
                    if !self.rest.is_empty() {
                        self.ready.push_back(Lane::Rest);
                    }
                    job
                }
                // A session that left has no job behind its lane.
                Lane::Session(id) => self.sessions.remove(&id),
            };
            if job.is_some() {
                return job;
            }
        }
        None
    }
}

struct Shared {
    queue: Mutex<Queue>,
    wake: Condvar,
    metrics: Metrics,
    rest_capacity: usize,
    /// Duration of the last render, for Retry-After estimates.
    last_render_ms: AtomicU32,
}

impl Shared {
    fn lock(&self) -> MutexGuard<'_, Queue> {
        self.queue.lock().unwrap_or_else(PoisonError::into_inner)
    }

    fn queued(&self, queue: &Queue) {
        self.metrics.queue_depth.set(i64::try_from(queue.depth()).unwrap_or(i64::MAX));
        self.wake.notify_one();
    }

    /// Blocks until a job is available; `None` once the pool is closed and drained. Also
    /// returns the sessions that ended meanwhile. Waiting art-map changes go to `apply_art`
    /// first (outside the lock), so a frame sees every change made before it was taken.
    /// The next job and the sessions that ended since the last call; `(None, ended)` when
    /// sessions ended and no job waits, so their view states are freed at once. `None` once
    /// the pool is closed and drained.
    fn next_job(&self, mut apply_art: impl FnMut(ArtJob)) -> Option<(Option<Job>, Vec<u64>)> {
        let mut queue = self.lock();
        loop {
            if let Some(art) = queue.art.pop_front() {
                drop(queue);
                apply_art(art);
                queue = self.lock();
                continue;
            }
            if let Some(job) = queue.pop() {
                self.metrics.queue_depth.set(i64::try_from(queue.depth()).unwrap_or(i64::MAX));
                return Some((Some(job), std::mem::take(&mut queue.left)));
            }
            if !queue.left.is_empty() {
                return Some((None, std::mem::take(&mut queue.left)));
            }
            if queue.closed {
                return None;
            }
            queue = self.wake.wait(queue).unwrap_or_else(PoisonError::into_inner);
        }
    }
}

/// The render queue and its worker thread.
pub struct RenderPool {
    shared: Arc<Shared>,
    worker: Mutex<Option<std::thread::JoinHandle<()>>>,
    /// The art maps the renderer was built with (the generated defaults).
    initial_art: ArtMapSet,
}

impl RenderPool {
    /// Starts the worker thread, builds the [`Renderer`] for `scene` on it and returns once it
    /// is ready (blocking). Data layers of views are read from `store` on the worker. At most
    /// `rest_capacity` REST renders wait at a time; encoding runs on `runtime`'s blocking pool.
    pub fn start(
        gpu: Arc<Gpu>,
        scene: Arc<Scene>,
        store: Arc<Store>,
        options: RenderOptions,
        rest_capacity: usize,
        metrics: Metrics,
        runtime: Handle,
    ) -> std::io::Result<RenderPool> {
        let shared = Arc::new(Shared {
            queue: Mutex::default(),
            wake: Condvar::new(),
            metrics,
            rest_capacity,
            last_render_ms: AtomicU32::new(0),
        });
        let (ready_tx, ready_rx) = std::sync::mpsc::channel();
        let worker_shared = shared.clone();
        let worker = std::thread::Builder::new().name("render".into()).spawn(move || {
            let renderer = Renderer::with_options(gpu, &scene, &options);
            drop(scene);
            // The receiver only goes away when `start` has returned already.
            match renderer {
                Ok(mut renderer) => {
                    let _ = ready_tx.send(Ok(renderer.art_maps().clone()));
                    work(&worker_shared, &mut renderer, &store, &runtime);
                }
                Err(error) => {
                    let _ = ready_tx.send(Err(error.to_string()));
                }
            }
        })?;
        let initial_art = ready_rx
            .recv()
            .map_err(|_| std::io::Error::other("the render thread died while building the renderer"))?
            .map_err(|message| std::io::Error::other(format!("cannot build the renderer: {message}")))?;
        Ok(RenderPool { shared, worker: Mutex::new(Some(worker)), initial_art })
    }

    /// Queues a REST render; refused when the REST lane is full or the pool is closed.
    pub fn submit(&self, view: ViewRequest) -> Result<FrameReceiver, PoolError> {
        let (job, receiver) = Job::new(view, FrameKind::Rest, None);
        self.queue_rest(job)?;
        Ok(receiver)
    }

    /// Queues a REST render of `view` that answers what `pixel` (`[column, row]`) shows
    /// instead of an image; refused like [`RenderPool::submit`].
    pub fn pick(&self, view: ViewRequest, pixel: [u32; 2]) -> Result<PickReceiver, PoolError> {
        let (reply, receiver) = oneshot::channel();
        self.queue_rest(Job { view, kind: FrameKind::Rest, session: None, reply: Reply::Pick { pixel, reply } })?;
        Ok(receiver)
    }

    fn queue_rest(&self, job: Job) -> Result<(), PoolError> {
        let mut queue = self.shared.lock();
        if queue.closed {
            return Err(PoolError::Closed);
        }
        if queue.rest.len() >= self.shared.rest_capacity {
            self.shared.metrics.queue_rejected.inc();
            let depth = queue.depth();
            let estimate_ms = depth as u64 * u64::from(self.shared.last_render_ms.load(Ordering::Relaxed));
            let retry_after_s = u32::try_from(estimate_ms.div_ceil(1000).max(1)).unwrap_or(u32::MAX);
            return Err(PoolError::Full { depth, retry_after_s });
        }
        if queue.rest.is_empty() {
            queue.ready.push_back(Lane::Rest);
        }
        queue.rest.push_back(job);
        self.shared.queued(&queue);
        Ok(())
    }

    /// Queues an art-map change; the worker applies it before its next frame and answers with
    /// the art maps after it. Refused once the pool is closed.
    pub fn change_art(&self, change: ArtChange) -> Result<ArtReceiver, PoolError> {
        let mut queue = self.shared.lock();
        if queue.closed {
            return Err(PoolError::Closed);
        }
        let (reply, receiver) = oneshot::channel();
        queue.art.push_back(ArtJob { change, reply });
        self.shared.wake.notify_one();
        Ok(receiver)
    }

    /// The art maps the renderer was built with: the generated defaults.
    pub fn initial_art_maps(&self) -> &ArtMapSet {
        &self.initial_art
    }

    /// A lane for one WebSocket session.
    pub fn session_lane(&self) -> SessionLane {
        let mut queue = self.shared.lock();
        queue.next_session += 1;
        SessionLane { id: queue.next_session, shared: self.shared.clone() }
    }

    /// Renders waiting for the worker.
    pub fn depth(&self) -> usize {
        self.shared.lock().depth()
    }

    /// Refuses new jobs; the worker finishes the queued ones and stops.
    pub fn close(&self) {
        self.shared.lock().closed = true;
        self.shared.wake.notify_all();
    }

    /// Closes the pool and waits (blocking) until the worker has finished every queued job.
    pub fn join(&self) {
        self.close();
        let worker = self.worker.lock().unwrap_or_else(PoisonError::into_inner).take();
        if let Some(worker) = worker
            && worker.join().is_err()
        {
            tracing::error!("the render thread panicked");
        }
    }
}

impl Drop for RenderPool {
    fn drop(&mut self) {
        self.close();
    }
}

/// The worker loop. REST views render without history (deterministic); each WebSocket session
/// keeps a [`ViewState`] so its hatching follows the camera from frame to frame (thesis
/// eq. 6.2), dropped when the session ends.
fn work(shared: &Shared, renderer: &mut Renderer, store: &Store, runtime: &Handle) {
    let mut views: HashMap<u64, ViewState> = HashMap::new();
    let mut layers = LayerCache::default();
    loop {
        let next = shared.next_job(|job| apply_art(renderer, job));
        let Some((job, left)) = next else { break };
        for id in left {
            views.remove(&id);
        }
        let Some(Job { view, kind, session, reply }) = job else { continue };
        if reply.is_closed() {
            continue; // the client left while the job waited
        }
        let started = Instant::now();
        let read = match reply {
            Reply::Pick { .. } => Readback { depth: true, ids: true },
            Reply::Frame(_) => Readback::default(),
        };
        let rendered = std::panic::catch_unwind(AssertUnwindSafe(|| {
            let data = layers.view(&view.data, store)?;
            let (camera, style, width, height) = (&view.camera, view.frame_style(), view.width, view.height);
            let request = FrameRequest::new(camera, style, width, height).data(&data).read(read);
            let request = match &view.compare {
                Some(compare) => request.compare(compare),
                None => request,
            };
            let request = request.pins(view.comments.as_deref().unwrap_or_default());
            let request = match session {
                Some(id) => request.history(views.entry(id).or_insert_with(|| renderer.new_view_state())),
                None => request,
            };
            renderer.render(request)
        }));
        let elapsed = started.elapsed();
        let render_ms = elapsed.as_secs_f32() * 1e3;
        shared.last_render_ms.store(render_ms.ceil() as u32, Ordering::Relaxed);
        shared.metrics.render_seconds.get_or_create(&kind.label()).observe(elapsed.as_secs_f64());
        for (pass, ms) in renderer.take_pass_times().unwrap_or_default() {
            shared.metrics.pass_seconds.get_or_create(&[("pass", pass)]).observe(ms / 1e3);
        }
        let reply = match reply {
            Reply::Frame(reply) => reply,
            Reply::Pick { pixel, reply } => {
                let picked = match rendered {
                    Ok(Ok(frame)) => pick_at(&frame, view.width, pixel),
                    Ok(Err(error)) => Err(PoolError::Render(error)),
                    Err(_) => Err(PoolError::Panicked),
                };
                // The client may have left; then nobody wants the answer.
                let _ = reply.send(picked);
                continue;
            }
        };
        let metrics = shared.metrics.clone();
        runtime.spawn_blocking(move || {
            let result = match rendered {
                Ok(Ok(frame)) => {
                    let started = Instant::now();
                    let encoded = view.format.encode(&frame.image, view.quality);
                    metrics.encode_seconds.observe(started.elapsed().as_secs_f64());
                    encoded.map(|bytes| Frame { bytes: Bytes::from(bytes), render_ms }).map_err(PoolError::from)
                }
                Ok(Err(error)) => Err(PoolError::Render(error)),
                Err(_) => Err(PoolError::Panicked),
            };
            // The client may have left in the meantime; then nobody wants the frame.
            let _ = reply.send(result);
        });
    }
}

/// What pixel `[x, y]` of a frame `width` pixels wide shows, from its read-back depth and ids.
fn pick_at(frame: &crate::render::renderer::Frame, width: u32, [x, y]: [u32; 2]) -> Result<Pick, PoolError> {
    let outside = PoolError::OutsideImage { x, y };
    if x >= width {
        return Err(outside);
    }
    let index = y as usize * width as usize + x as usize;
    let depth = frame.depth.as_ref().and_then(|d| d.get(index).copied());
    let object_id = frame.ids.as_ref().and_then(|ids| ids.get(index).copied());
    match (depth, object_id) {
        (Some(depth), Some(object_id)) => Ok(Pick { depth, object_id }),
        _ => Err(outside),
    }
}

/// Applies an art-map change on the worker and answers with the art maps after it.
fn apply_art(renderer: &mut Renderer, ArtJob { change, reply }: ArtJob) {
    let applied = std::panic::catch_unwind(AssertUnwindSafe(|| match change {
        ArtChange::Set { index, map } => renderer.set_art_map(index, map),
        ArtChange::Remove { kind, index } => renderer.remove_art_map(kind, index),
    }));
    let result = match applied {
        Ok(Ok(())) => Ok(renderer.art_maps().clone()),
        Ok(Err(error)) => Err(PoolError::Render(error)),
        Err(_) => Err(PoolError::Panicked),
    };
    // The requester may have left; the change stays applied either way.
    let _ = reply.send(result);
}

/// One WebSocket session's lane: at most one job, replaced by newer views until the worker
/// takes it (latest wins). Dropping the lane withdraws its job.
pub struct SessionLane {
    id: u64,
    shared: Arc<Shared>,
}

impl SessionLane {
    /// The session's number (unique within the pool).
    pub fn id(&self) -> u64 {
        self.id
    }

    /// Queues `view`; a job of this session that the worker has not started is replaced (its
    /// receiver then reports [`PoolError::Cancelled`]).
    pub fn render(&self, view: ViewRequest, kind: FrameKind) -> Result<FrameReceiver, PoolError> {
        let mut queue = self.shared.lock();
        if queue.closed {
            return Err(PoolError::Closed);
        }
        let (job, receiver) = Job::new(view, kind, Some(self.id));
        if queue.sessions.insert(self.id, job).is_none() {
            queue.ready.push_back(Lane::Session(self.id));
        }
        self.shared.queued(&queue);
        Ok(receiver)
    }

    /// Replaces this session's waiting job with `view`; `None` when no job is waiting (the
    /// worker has started it, or there was none).
    pub fn replace(&self, view: ViewRequest, kind: FrameKind) -> Option<FrameReceiver> {
        let mut queue = self.shared.lock();
        let slot = queue.sessions.get_mut(&self.id)?;
        let (job, receiver) = Job::new(view, kind, Some(self.id));
        *slot = job;
        Some(receiver)
    }
}

impl Drop for SessionLane {
    fn drop(&mut self) {
        let mut queue = self.shared.lock();
        queue.sessions.remove(&self.id);
        queue.left.push(self.id);
        self.shared.metrics.queue_depth.set(i64::try_from(queue.depth()).unwrap_or(i64::MAX));
        // Wake an idle worker so it frees the session's view state now.
        self.shared.wake.notify_all();
    }
}
