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
//!
//! Model data stays on the device: a client sends its element data with its first request
//! (and again only if it changed, which a client checks on its own thread), the batcher
//! registers it as a segment of the context's resident table, and every later request
//! carries only the per-iteration inputs; the round refers to each client's elements by
//! table slot. A dropped client releases its segment for the next client's reuse.
//! Residual-only requests (modified Newton) of a round go to the residual kernel in a
//! dispatch of their own.

use std::collections::HashMap;
use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering};
use std::sync::mpsc::{self, Receiver, RecvTimeoutError, Sender};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use super::{same_data, GpuContext, GpuTimes, ModelUploads, Segment};
use crate::element::{ElemData, ElemIn, ElemOut, ElementEval, EvalError};

struct Bufs {
    elems: Vec<ElemData>,
    inputs: Vec<ElemIn>,
    out: Vec<ElemOut>,
}

struct Request {
    client: u64,
    /// `bufs.elems` holds the client's element data, to be made resident
    register: bool,
    residual: bool,
    bufs: Bufs,
    inertia: bool,
    reply: Sender<(Bufs, Result<(), String>)>,
}

enum Msg {
    Eval(Request),
    /// a client is gone: its table segment is free
    Release(u64),
}

/// Statistics of a batcher's rounds.
#[derive(Clone, Copy, Debug, Default)]
pub struct BatchStats {
    pub gpu: GpuTimes,
    pub rounds: u64,
    pub requests: u64,
    /// of `requests`: residual-only ones
    pub residual_requests: u64,
    /// model data written to the device (once per client)
    pub model: ModelUploads,
}

/// The batcher thread and its queue.
pub struct Batcher {
    tx: Mutex<Option<Sender<Msg>>>,
    live: Arc<AtomicUsize>,
    next_id: AtomicU64,
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
        let (tx, rx) = mpsc::channel::<Msg>();
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
            next_id: AtomicU64::new(0),
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
            id: self.next_id.fetch_add(1, Ordering::SeqCst),
            registered: Mutex::new(None),
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
    rx: Receiver<Msg>,
    live: Arc<AtomicUsize>,
    stats: Arc<Mutex<BatchStats>>,
    max_wait: Duration,
) {
    let mut segs: HashMap<u64, Segment> = HashMap::new();
    let mut slots: Vec<u32> = Vec::new();
    let mut inputs: Vec<ElemIn> = Vec::new();
    let mut out: Vec<ElemOut> = Vec::new();
    let mut round: Vec<Request> = Vec::new();
    let release = |ctx: &mut GpuContext, segs: &mut HashMap<u64, Segment>, id: u64| {
        if let Some(s) = segs.remove(&id) {
            ctx.release(s);
        }
    };
    while let Ok(msg) = rx.recv() {
        let first = match msg {
            Msg::Eval(r) => r,
            Msg::Release(id) => {
                release(&mut ctx, &mut segs, id);
                continue;
            }
        };
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
                Ok(Msg::Eval(r)) => round.push(r),
                Ok(Msg::Release(id)) => release(&mut ctx, &mut segs, id),
                Err(RecvTimeoutError::Timeout) | Err(RecvTimeoutError::Disconnected) => break,
            }
        }
        // more requests may have queued meanwhile: take them too, the batch only grows
        while let Ok(m) = rx.try_recv() {
            match m {
                Msg::Eval(r) => round.push(r),
                Msg::Release(id) => release(&mut ctx, &mut segs, id),
            }
        }
        // make new (or changed) element data resident
        let mut failed: Vec<Option<String>> = vec![None; round.len()];
        for (k, r) in round.iter().enumerate() {
            if r.register {
                release(&mut ctx, &mut segs, r.client);
                match ctx.register(&r.bufs.elems) {
                    Ok(s) => {
                        segs.insert(r.client, s);
                    }
                    Err(e) => failed[k] = Some(e.to_string()),
                }
            }
            if failed[k].is_none() {
                match segs.get(&r.client) {
                    Some(s) if ctx.slots(*s).len() == r.bufs.inputs.len() => {}
                    _ => {
                        failed[k] = Some(format!(
                            "{} element inputs without their element data on the device",
                            r.bufs.inputs.len()
                        ))
                    }
                }
            }
        }
        let mut t = GpuTimes::default();
        let mut result: Vec<Result<(), String>> = vec![Ok(()); round.len()];
        // full and residual requests: one dispatch (chunked at the limit) each
        for residual in [false, true] {
            let members: Vec<usize> = (0..round.len())
                .filter(|&k| round[k].residual == residual && failed[k].is_none())
                .collect();
            if members.is_empty() {
                continue;
            }
            let inertia = members.iter().any(|&k| round[k].inertia);
            slots.clear();
            inputs.clear();
            for &k in &members {
                let r = &round[k];
                slots.extend(ctx.slots(segs[&r.client]));
                inputs.extend_from_slice(&r.bufs.inputs);
            }
            out.resize(inputs.len(), ElemOut::default());
            let max = ctx.max_elements().max(1);
            let mut res: Result<(), String> = Ok(());
            let mut start = 0;
            while start < inputs.len() && res.is_ok() {
                let end = (start + max).min(inputs.len());
                match ctx.evaluate_slots(
                    &slots[start..end],
                    &inputs[start..end],
                    residual,
                    inertia,
                    &mut out[start..end],
                ) {
                    Ok(tt) => t.add(&tt),
                    Err(e) => res = Err(e.to_string()),
                }
                start = end;
            }
            let mut off = 0;
            for &k in &members {
                let r = &mut round[k];
                let n = r.bufs.inputs.len();
                r.bufs.out.clear();
                r.bufs.out.extend_from_slice(&out[off..off + n]);
                off += n;
                result[k] = res.clone();
            }
        }
        {
            let mut s = stats.lock().unwrap_or_else(|p| p.into_inner());
            s.gpu.add(&t);
            s.rounds += 1;
            s.requests += round.len() as u64;
            s.residual_requests += round.iter().filter(|r| r.residual).count() as u64;
            s.model = ctx.model_uploads();
        }
        for (k, r) in round.drain(..).enumerate() {
            let Request {
                mut bufs,
                inertia: own,
                reply,
                ..
            } = r;
            if !own {
                // asked without inertia: M, S, C and the inertial forces are zero, as on
                // the CPU
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
            let res = match failed[k].take() {
                Some(e) => Err(e),
                None => result[k].clone(),
            };
            let _ = reply.send((bufs, res));
        }
    }
}

/// One solver's handle on the batcher (an [`ElementEval`]).
pub struct BatchClient {
    id: u64,
    /// the element data the batcher holds for this client (None before the first call)
    registered: Mutex<Option<Vec<ElemData>>>,
    batcher: Arc<Batcher>,
    tx: Mutex<Option<Sender<Msg>>>,
    bufs: Mutex<Option<Bufs>>,
}

impl Drop for BatchClient {
    fn drop(&mut self) {
        if let Some(tx) = self.tx.lock().unwrap_or_else(|p| p.into_inner()).as_ref() {
            let _ = tx.send(Msg::Release(self.id));
        }
        self.batcher.live.fetch_sub(1, Ordering::SeqCst);
    }
}

impl BatchClient {
    fn run(
        &self,
        residual: bool,
        elems: &[ElemData],
        inputs: &[ElemIn],
        inertia: bool,
        out: &mut [ElemOut],
    ) -> Result<(), EvalError> {
        let err = |m: String| EvalError {
            backend: self.batcher.name.clone(),
            message: m,
        };
        if elems.is_empty() {
            return Ok(());
        }
        let mut bufs = self
            .bufs
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .take()
            .ok_or_else(|| err("client buffers lost".into()))?;
        // the element data goes with the first request only (or when it changed)
        let register = {
            let mut reg = self.registered.lock().unwrap_or_else(|p| p.into_inner());
            let same = reg.as_deref().is_some_and(|r| same_data(r, elems));
            if !same {
                *reg = Some(elems.to_vec());
            }
            !same
        };
        bufs.elems.clear();
        if register {
            bufs.elems.extend_from_slice(elems);
        }
        bufs.inputs.clear();
        bufs.inputs.extend_from_slice(inputs);
        let (rtx, rrx) = mpsc::channel();
        {
            let tx = self.tx.lock().unwrap_or_else(|p| p.into_inner());
            let tx = tx.as_ref().ok_or_else(|| err("batcher stopped".into()))?;
            tx.send(Msg::Eval(Request {
                client: self.id,
                register,
                residual,
                bufs,
                inertia,
                reply: rtx,
            }))
            .map_err(|_| err("batcher stopped".into()))?;
        }
        let (bufs, result) = rrx.recv().map_err(|_| err("batcher stopped".into()))?;
        if result.is_err() {
            // the batcher may not hold the data: send it again next time
            *self.registered.lock().unwrap_or_else(|p| p.into_inner()) = None;
        } else {
            out.copy_from_slice(&bufs.out[..out.len()]);
        }
        *self.bufs.lock().unwrap_or_else(|p| p.into_inner()) = Some(bufs);
        result.map_err(err)
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
        self.run(false, elems, inputs, inertia, out)
    }
    fn evaluate_residual(
        &self,
        elems: &[ElemData],
        inputs: &[ElemIn],
        inertia: bool,
        out: &mut [ElemOut],
    ) -> Result<(), EvalError> {
        self.run(true, elems, inputs, inertia, out)
    }
    fn name(&self) -> String {
        self.batcher.name.clone()
    }
    fn unit_roundoff(&self) -> f64 {
        self.batcher.precision.unit_roundoff()
    }
}
