//! One GPU context shared by many solver threads: each variant of a GPU campaign runs the
//! unchanged CPU solver on its own OS thread, with a [`BatchClient`] as its element stage.
//! A client's `evaluate` sends its elements to the batcher thread and sleeps; the batcher
//! concatenates the requests it has, does one upload / dispatch / download for all of
//! them, and wakes each client with its slice of the results.
//!
//! When to dispatch: as soon as half of the live clients are waiting (or `max_wait` after
//! the first request of a round). With half the clients per round, one half factorizes
//! and assembles on the CPU while the GPU evaluates the other half's elements, so neither
//! side idles for long; waiting for all clients instead would alternate strictly (CPU
//! idle during the kernel, GPU idle during factorization). Requests own their buffers and
//! get them back with the reply, so a client allocates only on its first call.

use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::mpsc::{self, Receiver, RecvTimeoutError, Sender};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use super::{GpuContext, GpuTimes};
use crate::element::{ElemData, ElemIn, ElemOut, ElementEval, EvalError};

struct Bufs {
    elems: Vec<ElemData>,
    inputs: Vec<ElemIn>,
    out: Vec<ElemOut>,
}

struct Request {
    bufs: Bufs,
    inertia: bool,
    reply: Sender<(Bufs, Result<(), String>)>,
}

/// Statistics of a batcher's rounds.
#[derive(Clone, Copy, Debug, Default)]
pub struct BatchStats {
    pub gpu: GpuTimes,
    pub rounds: u64,
    pub requests: u64,
}

/// The batcher thread and its queue.
pub struct Batcher {
    tx: Mutex<Option<Sender<Request>>>,
    live: Arc<AtomicUsize>,
    stats: Arc<Mutex<BatchStats>>,
    thread: Mutex<Option<JoinHandle<()>>>,
    name: String,
    precision: super::Precision,
}

impl Batcher {
    /// Start the batcher thread on `ctx`; `max_wait` bounds how long a round waits for
    /// more clients after its first request.
    pub fn start(ctx: GpuContext, max_wait: Duration) -> Arc<Batcher> {
        let name = format!("gpu {} {}", ctx.adapter.label(), ctx.precision.as_str());
        let precision = ctx.precision;
        let (tx, rx) = mpsc::channel::<Request>();
        let live = Arc::new(AtomicUsize::new(0));
        let stats = Arc::new(Mutex::new(BatchStats::default()));
        let (l2, s2) = (live.clone(), stats.clone());
        let thread = std::thread::Builder::new()
            .name("latdyn-gpu".into())
            .spawn(move || serve(ctx, rx, l2, s2, max_wait))
            .ok();
        Arc::new(Batcher {
            tx: Mutex::new(Some(tx)),
            live,
            stats,
            thread: Mutex::new(thread),
            name,
            precision,
        })
    }

    /// A new client (one per solver); it counts as live until dropped.
    pub fn client(self: &Arc<Self>) -> Arc<BatchClient> {
        self.live.fetch_add(1, Ordering::SeqCst);
        let tx = self
            .tx
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .as_ref()
            .cloned();
        Arc::new(BatchClient {
            batcher: self.clone(),
            tx: Mutex::new(tx),
            bufs: Mutex::new(Some(Bufs {
                elems: Vec::new(),
                inputs: Vec::new(),
                out: Vec::new(),
            })),
        })
    }

    pub fn stats(&self) -> BatchStats {
        *self.stats.lock().unwrap_or_else(|p| p.into_inner())
    }

    pub fn name(&self) -> &str {
        &self.name
    }

    /// Stop the thread once every client is gone (also done on drop).
    pub fn shutdown(&self) {
        self.tx.lock().unwrap_or_else(|p| p.into_inner()).take();
        if let Some(h) = self.thread.lock().unwrap_or_else(|p| p.into_inner()).take() {
            let _ = h.join();
        }
    }
}

impl Drop for Batcher {
    fn drop(&mut self) {
        self.shutdown();
    }
}

fn serve(
    mut ctx: GpuContext,
    rx: Receiver<Request>,
    live: Arc<AtomicUsize>,
    stats: Arc<Mutex<BatchStats>>,
    max_wait: Duration,
) {
    let mut elems: Vec<ElemData> = Vec::new();
    let mut inputs: Vec<ElemIn> = Vec::new();
    let mut out: Vec<ElemOut> = Vec::new();
    let mut round: Vec<Request> = Vec::new();
    while let Ok(first) = rx.recv() {
        round.clear();
        round.push(first);
        let deadline = Instant::now() + max_wait;
        loop {
            let target = live.load(Ordering::SeqCst).div_ceil(2).max(1);
            if round.len() >= target {
                break;
            }
            let now = Instant::now();
            if now >= deadline {
                break;
            }
            match rx.recv_timeout(deadline - now) {
                Ok(r) => round.push(r),
                Err(RecvTimeoutError::Timeout) | Err(RecvTimeoutError::Disconnected) => break,
            }
        }
        // more requests may have queued meanwhile: take them too, the batch only grows
        while let Ok(r) = rx.try_recv() {
            round.push(r);
        }
        let inertia = round.iter().any(|r| r.inertia);
        elems.clear();
        inputs.clear();
        for r in &round {
            elems.extend_from_slice(&r.bufs.elems);
            inputs.extend_from_slice(&r.bufs.inputs);
        }
        out.resize(elems.len(), ElemOut::default());
        // the round's elements may exceed one dispatch: split into chunks
        let max = ctx.max_elements().max(1);
        let mut result: Result<(), String> = Ok(());
        let mut t = GpuTimes::default();
        let mut start = 0;
        while start < elems.len() && result.is_ok() {
            let end = (start + max).min(elems.len());
            match ctx.evaluate(
                &elems[start..end],
                &inputs[start..end],
                inertia,
                &mut out[start..end],
            ) {
                Ok(tt) => t.add(&tt),
                Err(e) => result = Err(e.to_string()),
            }
            start = end;
        }
        {
            let mut s = stats.lock().unwrap_or_else(|p| p.into_inner());
            s.gpu.add(&t);
            s.rounds += 1;
            s.requests += round.len() as u64;
        }
        let mut off = 0;
        for r in round.drain(..) {
            let Request {
                mut bufs,
                inertia: own,
                reply,
            } = r;
            let n = bufs.elems.len();
            bufs.out.clear();
            bufs.out.extend_from_slice(&out[off..off + n]);
            if !own {
                // asked without inertia: M, S, C are zero, as on the CPU
                for o in bufs.out.iter_mut() {
                    let f = o.f;
                    let k = o.k;
                    let e = o.energy;
                    *o = ElemOut::default();
                    o.f = f;
                    o.k = k;
                    o.energy = e;
                }
            }
            off += n;
            let _ = reply.send((bufs, result.clone()));
        }
    }
}

/// One solver's handle on the batcher (an [`ElementEval`]).
pub struct BatchClient {
    batcher: Arc<Batcher>,
    tx: Mutex<Option<Sender<Request>>>,
    bufs: Mutex<Option<Bufs>>,
}

impl Drop for BatchClient {
    fn drop(&mut self) {
        self.batcher.live.fetch_sub(1, Ordering::SeqCst);
    }
}

impl ElementEval for BatchClient {
    fn evaluate(
        &self,
        elems: &[ElemData],
        inputs: &[ElemIn],
        inertia: bool,
        out: &mut [ElemOut],
    ) -> Result<(), EvalError> {
        let err = |m: String| EvalError {
            backend: self.batcher.name.clone(),
            message: m,
        };
        let mut bufs = self
            .bufs
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .take()
            .ok_or_else(|| err("client buffers lost".into()))?;
        bufs.elems.clear();
        bufs.elems.extend_from_slice(elems);
        bufs.inputs.clear();
        bufs.inputs.extend_from_slice(inputs);
        let (rtx, rrx) = mpsc::channel();
        {
            let tx = self.tx.lock().unwrap_or_else(|p| p.into_inner());
            let tx = tx.as_ref().ok_or_else(|| err("batcher stopped".into()))?;
            tx.send(Request {
                bufs,
                inertia,
                reply: rtx,
            })
            .map_err(|_| err("batcher stopped".into()))?;
        }
        let (bufs, result) = rrx.recv().map_err(|_| err("batcher stopped".into()))?;
        out.copy_from_slice(&bufs.out[..out.len()]);
        *self.bufs.lock().unwrap_or_else(|p| p.into_inner()) = Some(bufs);
        result.map_err(err)
    }
    fn name(&self) -> String {
        self.batcher.name.clone()
    }
    fn unit_roundoff(&self) -> f64 {
        self.batcher.precision.unit_roundoff()
    }
}
