//! Per-batch accumulators of the photon engine: sparse per-element tallies ([`Acc`]), one
//! batch's outputs ([`BatchOut`]) and the receiver tally interface ([`ReturnTally`]) that
//! receiver (LiDAR) mode books into (DART 5 paper §4; physics.md §9.4).

use rand_xoshiro::Xoshiro256PlusPlus;
use std::collections::HashMap;

/// Per-element accumulator (dense when small, hashed otherwise).
pub(crate) struct Acc {
    pub(crate) width: usize,
    pub(crate) dense: Option<Vec<f64>>,
    pub(crate) sparse: HashMap<u32, Vec<f64>>,
    /// Discards everything (LiDAR pulses keep no radiative budget).
    pub(crate) sink: bool,
}

impl Acc {
    pub(crate) fn new(n: usize, width: usize) -> Self {
        let dense = (n * width <= 1 << 18).then(|| vec![0.0; n * width]);
        Self {
            width,
            dense,
            sparse: HashMap::new(),
            sink: false,
        }
    }
    /// All records back to zero (a sink reused for the next pulse).
    pub(crate) fn reset(&mut self) {
        if let Some(d) = self.dense.as_mut() {
            d.fill(0.0);
        }
        self.sparse.clear();
    }
    pub(crate) fn sink(width: usize) -> Self {
        Self {
            width,
            dense: Some(vec![0.0; width]),
            sparse: HashMap::new(),
            sink: true,
        }
    }
    /// The record of `key` (a sink: its scratch record), inlined up to the record lookup
    /// (every LiDAR event books into sinks).
    #[inline(always)]
    pub(crate) fn get(&mut self, key: u32) -> &mut [f64] {
        let w = self.width;
        if self.sink {
            return &mut self.dense.as_mut().expect("sink buffer")[..w];
        }
        self.record(key)
    }

    /// [`Acc::get`] of a non-sink accumulator.
    #[inline(never)]
    pub(crate) fn record(&mut self, key: u32) -> &mut [f64] {
        let w = self.width;
        match &mut self.dense {
            Some(d) => &mut d[key as usize * w..(key as usize + 1) * w],
            None => self.sparse.entry(key).or_insert_with(|| vec![0.0; w]),
        }
    }
    /// Visits every record (dense: all keys; sparse: sorted keys).
    pub(crate) fn for_each(&self, mut f: impl FnMut(u32, &[f64])) {
        if self.sink {
            return;
        }
        match &self.dense {
            Some(d) => {
                for (k, v) in d.chunks(self.width).enumerate() {
                    f(k as u32, v)
                }
            }
            None => {
                let mut keys: Vec<&u32> = self.sparse.keys().collect();
                keys.sort_unstable();
                for k in keys {
                    f(*k, &self.sparse[k])
                }
            }
        }
    }

    pub(crate) fn add_into(&self, out: &mut [f64]) {
        match &self.dense {
            Some(d) => out.iter_mut().zip(d).for_each(|(o, v)| *o += v),
            None => {
                // Keys in sorted order: merging is deterministic.
                let mut keys: Vec<&u32> = self.sparse.keys().collect();
                keys.sort_unstable();
                for k in keys {
                    let v = &self.sparse[k];
                    let s = *k as usize * self.width;
                    out[s..s + self.width]
                        .iter_mut()
                        .zip(v)
                        .for_each(|(o, x)| *o += x);
                }
            }
        }
    }
}

/// Tallies of one batch.
pub(crate) struct BatchOut {
    pub(crate) summary: Vec<f64>,
    pub(crate) abs_tur: Acc,
    pub(crate) int_tur: Acc,
    pub(crate) abs_fac: Acc,
    pub(crate) int_fac: Acc,
    pub(crate) abs_gnd: Acc,
    pub(crate) int_gnd: Acc,
    pub(crate) abs_fluid: HashMap<u32, Vec<f64>>,
    pub(crate) lost: Vec<f64>,
    pub(crate) roulette: Vec<f64>,
    pub(crate) events: u64,
    pub(crate) crossings: u64,
    pub(crate) skipped: u64,
    /// LiDAR receiver tallies (receiver mode only).
    pub(crate) wave: Option<Box<dyn ReturnTally>>,
    /// Camera pixel radiances, W m⁻² sr⁻¹: per camera, pixel `i + nx·j`, channel (empty
    /// without cameras; see `camera::CameraPeel`).
    pub(crate) cams: Vec<f64>,
}

/// What receiver-mode peel-offs are booked into: the LiDAR waveform binner of the pulse
/// tracking (`lidar::tracking`), seen by the photon walk only through path lengths, energies
/// and scattering orders (DART 5 paper §4; physics.md §9.4).
pub(crate) trait ReturnTally: Send + std::any::Any {
    /// Books the energy `energy_j` (J) received at the path length `path_m` (m, emitter to
    /// receiver) from scattering order `order` (what falls outside the gate is accounted as
    /// such by the tally).
    fn book(&mut self, path_m: f64, energy_j: f64, order: u32);
    /// Bins the expected-value first-order return of one vegetation segment of the first
    /// flight: segment start at distance `l0` (m) from the receiver, length `ell` (m), total
    /// extinction `alpha` (m⁻¹, outgoing plus return), energy density
    /// `base · e^{−αu}/(l0 + u)²` J m⁻¹ at the distance `u` from the segment start; stratified
    /// by digitiser bin, with draws from `rng`.
    fn first_order_segment(
        &mut self,
        l0: f64,
        ell: f64,
        alpha: f64,
        base: f64,
        rng: &mut Xoshiro256PlusPlus,
    );
    /// The tally itself (the tracking that created it takes its waveform back).
    fn as_any_mut(&mut self) -> &mut dyn std::any::Any;
}
