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
use std::sync::atomic::{AtomicUsize, Ordering};
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

/// Most chunk outputs held at once on `threads` workers (finished and waiting for their turn
/// to be merged, or running): see [`ahead`].
pub fn chunks_in_flight(threads: usize) -> usize {
    ahead(threads) + threads.max(1)
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
    merge_one: M,
) where
    W: Fn(usize, &mut ChunkOut) + Sync,
    M: FnMut(&ChunkOut) + Send,
{
    if n == 0 {
        return;
    }
    let threads = rayon::current_num_threads().max(1);
    let ahead = ahead(threads);
    let recycled = Mutex::new(std::mem::take(pools));
    // Chunks finished and not yet merged, and the next chunk to merge.
    let ready: Mutex<(BTreeMap<usize, ChunkOut>, usize)> = Mutex::new((BTreeMap::new(), 0));
    let merged = AtomicUsize::new(0);
    let merger = Mutex::new(merge_one);
    // Claims: the next chunk to start; workers wait on `room` while it is `ahead` chunks past
    // the last merged one.
    let claim = Mutex::new(0usize);
    let room = Condvar::new();
    // Merges the ready prefix; returns when another worker is merging (it rechecks after
    // releasing) or the next chunk is not finished.
    let drain = || {
        loop {
            let Ok(mut merge) = merger.try_lock() else {
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
                (*merge)(&out);
                let mut out = out;
                out.reset();
                lock(&recycled).outs.push(out);
                progress.inc(1);
                let mut r = lock(&ready);
                r.1 += 1;
                merged.store(r.1, Ordering::Release);
                drop(r);
                // Under the claim lock, so that a worker about to wait cannot miss it.
                let _c = lock(&claim);
                room.notify_all();
            }
            drop(merge);
            let r = lock(&ready);
            if !r.0.contains_key(&r.1) {
                return;
            }
        }
    };
    let worker = || {
        loop {
            let i = {
                let mut c = lock(&claim);
                loop {
                    if *c >= n {
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
            lock(&ready).0.insert(i, out);
            drain();
        }
    };
    rayon::scope(|s| {
        for _ in 0..threads {
            s.spawn(|_| worker());
        }
    });
    // Every chunk is merged by the workers' last drains; this is a guard, not a path.
    drain();
    debug_assert_eq!(merged.load(Ordering::Acquire), n, "every chunk merged");
    *pools = recycled.into_inner().unwrap_or_else(|e| e.into_inner());
}

/// A mutex's guard, also after a panic elsewhere poisoned it (the panic is propagated by the
/// scope; the data is not used after it).
fn lock<T>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|e| e.into_inner())
}
