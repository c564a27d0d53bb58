//! The chunk scheduler of the flux tracking: every pass (the launch, each scattering
//! iteration) is cut into chunks of emitters that the worker threads run in parallel, and
//! whose outputs are merged into the stores strictly in chunk order as soon as each is
//! finished (physics.md §6.4). Products are therefore bit-identical on any number of threads,
//! and only the chunks in flight are held in memory: at most [`ahead`] chunks are started
//! beyond the last merged one, whatever the number of chunks.
//!
//! Each worker lends its one turbid accumulator ([`TurAcc`], dense up to
//! [`DENSE_BYTES`]) to the chunk it runs; when the chunk ends, its records are compacted
//! into the chunk's output ([`CompactTur`]) and the accumulator is zeroed where it was
//! written, for the worker's next chunk. Chunk outputs and accumulators are recycled across
//! passes ([`Pools`]).

use super::*;
use std::collections::BTreeMap;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Condvar, Mutex};

/// Recycled chunk outputs (emptied) and worker accumulators (zeroed), kept across the passes
/// of one run.
#[derive(Default)]
pub(in crate::radiative) struct Pools {
    outs: Vec<ChunkOut>,
    /// Boxed: lent to a chunk as [`ChunkOut::tur`] and given back by moving a pointer.
    #[allow(clippy::vec_box)]
    accs: Vec<Box<TurAcc>>,
}

/// Chunks a worker may start beyond the last merged chunk, on `threads` workers: enough
/// that a slow chunk does not stall the others, few enough to bound the memory held.
pub fn ahead(threads: usize) -> usize {
    2 * threads.max(1) + 2
}

/// Runs the chunks `0..n` of one pass: `work(i, out)` fills chunk `i`'s output on some worker
/// thread, then `merge_one(out)` is called for the outputs in the order 0, 1, …, n−1 (under a
/// lock, by whichever worker finished the chunk that completes the prefix), and `progress`
/// advances by one per merged chunk.
pub(in crate::radiative) fn stream_chunks<W, M>(
    ctx: &Ctx,
    n: usize,
    pools: &mut Pools,
    progress: &indicatif::ProgressBar,
    work: W,
    mut merge_one: M,
) where
    W: Fn(usize, &mut ChunkOut) + Sync,
    M: FnMut(&ChunkOut) + Send,
{
    let recycled = Mutex::new(std::mem::take(pools));
    ordered(
        n,
        rayon::current_num_threads(),
        |i| {
            let (out, acc) = {
                let mut p = lock(&recycled);
                (p.outs.pop(), p.accs.pop())
            };
            let mut out = out.unwrap_or_else(|| new_out(ctx));
            out.tur = Some(acc.unwrap_or_else(|| new_acc(ctx)));
            work(i, &mut out);
            debug_assert!(out.queue.is_empty(), "every queued ray walked");
            let mut acc = out.tur.take().expect("the lent accumulator");
            out.ctur.take_from(&mut acc, ctx.w);
            lock(&recycled).accs.push(acc);
            out
        },
        |mut out| {
            merge_one(&out);
            out.reset();
            lock(&recycled).outs.push(out);
            progress.inc(1);
        },
    );
    *pools = recycled.into_inner().unwrap_or_else(|e| e.into_inner());
}

/// The scheduler of [`stream_chunks`], for any output type: `produce(i)` runs for every
/// `i < n` on `threads` workers (claimed in order, never more than [`ahead`] past the last
/// consumed one), and `consume` gets the outputs in the order 0, 1, …, n−1, as soon as the
/// prefix is complete, under a lock, on whichever worker completed it. A panic in `produce` or
/// `consume` is propagated to the caller once the other workers have stopped (they stop
/// claiming instead of waiting for the chunk that will never come).
pub(in crate::radiative) fn ordered<O, P, C>(n: usize, threads: usize, produce: P, consume: C)
where
    O: Send,
    P: Fn(usize) -> O + Sync,
    C: FnMut(O) + Send,
{
    if n == 0 {
        return;
    }
    let threads = threads.max(1);
    let ahead = ahead(threads);
    // Outputs finished and not yet consumed, and the next one to consume.
    let ready: Mutex<(BTreeMap<usize, O>, usize)> = Mutex::new((BTreeMap::new(), 0));
    let merged = AtomicUsize::new(0);
    let merger = Mutex::new(consume);
    // Claims: the next chunk to start; workers wait on `room` while it is `ahead` chunks past
    // the last consumed one.
    let claim = Mutex::new(0usize);
    let room = Condvar::new();
    let aborted = AtomicBool::new(false);
    // Consumes the ready prefix; returns when another worker is consuming (it rechecks after
    // releasing) or the next output is not finished.
    let drain = || {
        loop {
            let Ok(mut consume) = merger.try_lock() else {
                return;
            };
            loop {
                let out = {
                    let mut r = lock(&ready);
                    let next = r.1;
                    match r.0.remove(&next) {
                        Some(o) => o,
                        None => break,
                    }
                };
                (*consume)(out);
                let mut r = lock(&ready);
                r.1 += 1;
                merged.store(r.1, Ordering::Release);
                drop(r);
                // Under the claim lock, so that a worker about to wait cannot miss it.
                let _c = lock(&claim);
                room.notify_all();
            }
            drop(consume);
            let r = lock(&ready);
            if !r.0.contains_key(&r.1) {
                return;
            }
        }
    };
    let worker = || {
        // Set if this worker unwinds: the others stop claiming and waiting.
        let _guard = AbortOnPanic {
            aborted: &aborted,
            claim: &claim,
            room: &room,
        };
        loop {
            let i = {
                let mut c = lock(&claim);
                loop {
                    if *c >= n || aborted.load(Ordering::Acquire) {
                        return;
                    }
                    if *c < merged.load(Ordering::Acquire) + ahead {
                        break;
                    }
                    c = room.wait(c).unwrap_or_else(|e| e.into_inner());
                }
                *c += 1;
                *c - 1
            };
            let out = produce(i);
            lock(&ready).0.insert(i, out);
            drain();
        }
    };
    rayon::scope(|s| {
        for _ in 0..threads {
            s.spawn(|_| worker());
        }
    });
    // Every output is consumed by the workers' last drains; this is a guard, not a path.
    drain();
    debug_assert_eq!(merged.load(Ordering::Acquire), n, "every chunk consumed");
}

/// Sets `aborted` and wakes the waiting workers when dropped during a panic (see [`ordered`]).
struct AbortOnPanic<'a> {
    aborted: &'a AtomicBool,
    claim: &'a Mutex<usize>,
    room: &'a Condvar,
}

impl Drop for AbortOnPanic<'_> {
    fn drop(&mut self) {
        if std::thread::panicking() {
            self.aborted.store(true, Ordering::Release);
            let _c = lock(self.claim);
            self.room.notify_all();
        }
    }
}

/// A mutex's guard, also after a panic elsewhere poisoned it (the panic is propagated by the
/// scope; the data is not used after it).
fn lock<T>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|e| e.into_inner())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Outputs are consumed in chunk order whatever finishes first (chunks of uneven,
    /// pseudo-random duration on 1, 2 and 8 threads), each exactly once, with never more than
    /// `ahead` chunks started past the last consumed one.
    #[test]
    fn outputs_are_consumed_in_chunk_order_on_any_thread_count() {
        for threads in [1, 2, 8] {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .expect("pool");
            let n = 300;
            let consumed = AtomicUsize::new(0);
            let started_ahead = AtomicUsize::new(0);
            let mut order = Vec::new();
            pool.install(|| {
                ordered(
                    n,
                    threads,
                    |i| {
                        let lead = i.saturating_sub(consumed.load(Ordering::Acquire));
                        started_ahead.fetch_max(lead, Ordering::AcqRel);
                        // Uneven work: a few microseconds to a millisecond.
                        let spin = (i * 7919) % 13 * 80;
                        std::thread::sleep(std::time::Duration::from_micros(spin as u64));
                        i
                    },
                    |i| {
                        order.push(i);
                        consumed.fetch_add(1, Ordering::AcqRel);
                    },
                )
            });
            assert_eq!(order, (0..n).collect::<Vec<_>>(), "{threads} threads");
            assert!(
                started_ahead.load(Ordering::Acquire) <= ahead(threads),
                "{threads} threads: a chunk started {} past the last consumed",
                started_ahead.load(Ordering::Acquire)
            );
        }
    }

    /// A panic in one chunk reaches the caller; the other workers stop instead of waiting
    /// forever for that chunk's turn.
    #[test]
    fn a_panicking_chunk_is_propagated_not_hung() {
        // On its own thread, so that a hang fails the test after 30 s instead of hanging it.
        let (tx, rx) = std::sync::mpsc::channel();
        std::thread::spawn(move || {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(2)
                .build()
                .expect("pool");
            let r = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
                pool.install(|| {
                    ordered(
                        200,
                        2,
                        |i| {
                            if i == 3 {
                                panic!("chunk 3 fails");
                            }
                            std::thread::sleep(std::time::Duration::from_micros(200));
                            i
                        },
                        |_| {},
                    )
                })
            }));
            let _ = tx.send(r.is_err());
        });
        match rx.recv_timeout(std::time::Duration::from_secs(30)) {
            Ok(panicked) => assert!(panicked, "the panic reaches the caller"),
            Err(_) => panic!("the scheduler hung after a chunk panicked"),
        }
    }
}
