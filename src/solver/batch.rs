//! The batch dimension: several variants of a campaign advance in lockstep on one thread,
//! and every round of their Newton iterations' element stages is one call of
//! [`ElementEval::evaluate_batch`].
//!
//! The integrator is written once, as `async` code whose only await point is the element
//! stage of [`crate::assembly::Assembler`]. An assembler without a [`Slot`] evaluates on the
//! spot, so [`block_on`] finishes such a future in one poll (statics, modes, path following
//! and the synchronous `Integrator` API keep their cost). An assembler with a slot moves its
//! gathered inputs and output buffers into the slot (no copy) and pends; [`drive`] polls
//! every variant of its batch until each has either finished or posted its request,
//! evaluates all posted requests in one call, hands the buffers back and polls again. A
//! variant that needs more Newton iterations, or shorter steps, simply posts in more
//! rounds; one that fails or panics leaves the batch without holding up the others.
//!
//! Variants are not synchronised at output times: each round takes whatever the live
//! variants post, which keeps the batch as full as the number of live variants allows
//! (waiting at a grid time would idle the variants that got there first).

use std::future::Future;
use std::pin::Pin;
use std::sync::{Arc, Mutex};
use std::task::{Context, Poll, Waker};
use std::time::Instant;

use crate::element::{ElemData, ElemIn, ElemOut, ElementEval, EvalError, EvalRequest};

/// One variant's element-stage request, owned while it waits for its round.
pub(crate) struct Posted {
    pub inputs: Vec<ElemIn>,
    pub out: Vec<ElemOut>,
    pub residual: bool,
    pub inertia: bool,
}

/// The buffers of a request handed back, with the round's result and this request's share
/// of the round's wall time [s] (by element count).
pub(crate) struct Done {
    pub inputs: Vec<ElemIn>,
    pub out: Vec<ElemOut>,
    pub result: Result<(), EvalError>,
    pub secs: f64,
}

enum SlotState {
    Idle,
    Posted(Posted),
    Done(Done),
}

/// Where one variant of a batch posts its element-stage request and picks up the result.
/// Only the driver's thread touches it; the mutex makes it shareable without `unsafe`.
pub(crate) struct Slot(Mutex<SlotState>);

impl Slot {
    pub(crate) fn new() -> Arc<Slot> {
        Arc::new(Slot(Mutex::new(SlotState::Idle)))
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, SlotState> {
        self.0.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// Post a request and wait for the round that evaluates it.
    pub(crate) fn evaluate(&self, req: Posted) -> impl Future<Output = Done> + '_ {
        *self.lock() = SlotState::Posted(req);
        Wait { slot: self }
    }

    fn take_posted(&self) -> Option<Posted> {
        let mut g = self.lock();
        match std::mem::replace(&mut *g, SlotState::Idle) {
            SlotState::Posted(p) => Some(p),
            other => {
                *g = other;
                None
            }
        }
    }

    fn complete(&self, d: Done) {
        *self.lock() = SlotState::Done(d);
    }
}

struct Wait<'s> {
    slot: &'s Slot,
}

impl Future for Wait<'_> {
    type Output = Done;
    fn poll(self: Pin<&mut Self>, _: &mut Context<'_>) -> Poll<Done> {
        let mut g = self.slot.lock();
        match std::mem::replace(&mut *g, SlotState::Idle) {
            SlotState::Done(d) => Poll::Ready(d),
            other => {
                *g = other;
                Poll::Pending
            }
        }
    }
}

/// Run a future whose element stages all evaluate on the spot (no [`Slot`] on the way):
/// it finishes in its first poll.
pub(crate) fn block_on<F: Future>(f: F) -> F::Output {
    let mut f = std::pin::pin!(f);
    let mut cx = Context::from_waker(Waker::noop());
    match f.as_mut().poll(&mut cx) {
        Poll::Ready(v) => v,
        // only a slot pends, and the synchronous entry points build no slot
        Poll::Pending => unreachable!("an element stage without a batch slot pended"),
    }
}

/// Counts of a batch's element-stage calls.
#[derive(Clone, Copy, Debug, Default)]
pub struct BatchCounts {
    /// calls of [`ElementEval::evaluate_batch`]
    pub calls: u64,
    /// requests (one variant's elements each) over all calls
    pub requests: u64,
}

impl BatchCounts {
    pub fn add(&mut self, o: &BatchCounts) {
        self.calls += o.calls;
        self.requests += o.requests;
    }
}

/// One variant of a batch: its element data, its slot, and its run (posting to that slot).
pub(crate) struct Member<'a, T> {
    pub elems: &'a [ElemData],
    pub slot: Arc<Slot>,
    pub run: Pin<Box<dyn Future<Output = T> + 'a>>,
}

/// Advance the members in lockstep until all have finished, evaluating each round's
/// requests in one `eval.evaluate_batch` call. `on_done(i, result)` sees member i's output
/// as soon as it finishes, or the panic that ended it (caught, so the others go on).
pub(crate) fn drive<'a, T>(
    eval: &dyn ElementEval,
    members: Vec<Member<'a, T>>,
    mut on_done: impl FnMut(usize, std::thread::Result<T>),
) -> BatchCounts {
    let mut cx = Context::from_waker(Waker::noop());
    let mut members: Vec<Option<Member<'a, T>>> = members.into_iter().map(Some).collect();
    let mut counts = BatchCounts::default();
    let mut posted: Vec<(usize, Posted)> = Vec::with_capacity(members.len());
    while members.iter().any(Option::is_some) {
        for (i, slot) in members.iter_mut().enumerate() {
            let Some(m) = slot else { continue };
            let polled = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
                m.run.as_mut().poll(&mut cx)
            }));
            let finished = match polled {
                Ok(Poll::Pending) => match m.slot.take_posted() {
                    Some(p) => {
                        posted.push((i, p));
                        None
                    }
                    // nothing would ever wake it: end it as the bug it is
                    None => Some(Err(Box::new(
                        "a batch member pended without posting a request".to_string(),
                    ) as Box<dyn std::any::Any + Send>)),
                },
                Ok(Poll::Ready(v)) => Some(Ok(v)),
                Err(panic) => Some(Err(panic)),
            };
            if let Some(r) = finished {
                *slot = None;
                on_done(i, r);
            }
        }
        if posted.is_empty() {
            continue;
        }
        let t0 = Instant::now();
        let result = {
            let mut reqs: Vec<EvalRequest<'_>> = posted
                .iter_mut()
                .map(|(i, p)| EvalRequest {
                    elems: members[*i].as_ref().map_or(&[][..], |m| m.elems),
                    inputs: &p.inputs,
                    out: &mut p.out,
                    residual: p.residual,
                    inertia: p.inertia,
                })
                .collect();
            std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
                eval.evaluate_batch(&mut reqs)
            }))
            .unwrap_or_else(|panic| {
                Err(EvalError {
                    backend: eval.name(),
                    message: format!("panicked: {}", panic_message(&*panic)),
                })
            })
        };
        let secs = t0.elapsed().as_secs_f64();
        counts.calls += 1;
        counts.requests += posted.len() as u64;
        let total: usize = posted.iter().map(|(_, p)| p.inputs.len()).sum();
        for (i, p) in posted.drain(..) {
            let share = if total > 0 {
                secs * p.inputs.len() as f64 / total as f64
            } else {
                0.0
            };
            if let Some(m) = &members[i] {
                m.slot.complete(Done {
                    inputs: p.inputs,
                    out: p.out,
                    result: result.clone(),
                    secs: share,
                });
            }
        }
    }
    counts
}

/// The message of a caught panic.
pub fn panic_message(panic: &(dyn std::any::Any + Send)) -> String {
    panic
        .downcast_ref::<String>()
        .cloned()
        .or_else(|| panic.downcast_ref::<&str>().map(|s| s.to_string()))
        .unwrap_or_else(|| "unknown".into())
}
