//! LiDAR waveforms: path-length binning of received packets, convolution with the emitted pulse
//! and receiver response, and analytic first-order waveforms used as test oracles
//! (physics.md §9.1 "Range ↔ time", §9.4, §9.6, §13 item 12).
//!
//! Time axis: `t = L/c` with L the total (two-way) path length from emitter to receiver and
//! c = 299 792 458 m s⁻¹; a monostatic single-scattering return at range r has `t = 2r/c`.
//! Bin i covers `[t0 + iΔt, t0 + (i+1)Δt)` (ns); values are energies per bin (J).

use super::pulse::{PulseKernel, PulseShape};
use super::{
    LidarError, NeumaierSum, SPEED_OF_LIGHT_M_PER_S, check_non_negative, check_positive,
    check_unit_interval, compensated_sum,
};
use std::f64::consts::PI;

/// Largest number of bins a gate may have (bounds memory: 2 × 8 bytes × 5e7 = 800 MB).
pub const MAX_BINS: usize = 50_000_000;

/// Path length (m) travelled by light in `t_ns` nanoseconds.
pub fn path_m_from_time_ns(t_ns: f64) -> f64 {
    t_ns * 1e-9 * SPEED_OF_LIGHT_M_PER_S
}

/// Travel time (ns) of a path of `path_m` metres.
pub fn time_ns_from_path_m(path_m: f64) -> f64 {
    path_m / SPEED_OF_LIGHT_M_PER_S * 1e9
}

/// Monostatic range (m) of a return at two-way time `t_ns`: `r = c t / 2`.
pub fn range_m_from_time_ns(t_ns: f64) -> f64 {
    0.5 * path_m_from_time_ns(t_ns)
}

/// A received waveform: energy per time bin (J), total and first scattering order only.
#[derive(Debug, Clone, PartialEq)]
pub struct Waveform {
    /// Start time of bin 0 (ns, `t = L/c`).
    pub t0_ns: f64,
    /// Bin width (ns).
    pub dt_ns: f64,
    /// Energy per bin, all scattering orders (J).
    pub total: Vec<f64>,
    /// Energy per bin from first-order (single-scattering) packets only (J).
    pub first_order: Vec<f64>,
}

impl Waveform {
    /// A zero waveform of `n_bins` bins.
    pub fn zeros(t0_ns: f64, dt_ns: f64, n_bins: usize) -> Self {
        Self {
            t0_ns,
            dt_ns,
            total: vec![0.0; n_bins],
            first_order: vec![0.0; n_bins],
        }
    }

    /// Number of bins.
    pub fn n_bins(&self) -> usize {
        self.total.len()
    }

    /// Whether the waveform has no bins.
    pub fn is_empty(&self) -> bool {
        self.total.is_empty()
    }

    /// Drops the leading and trailing bins where both channels are exactly zero and moves
    /// `t0_ns` to the first kept bin; returns the number of leading bins dropped (the kept bin
    /// `i` is bin `i + returned` of the original axis). Energies and the values of the kept
    /// bins are unchanged (a waveform of zeros becomes empty, `t0_ns` unchanged). Stored
    /// waveforms of a scan are trimmed so that memory follows the returns' extent, not the
    /// range gate (a 250 000-pulse urban scan held 1.7 GiB of mostly-zero gate bins).
    pub fn trim(&mut self) -> usize {
        let nz = |i: &usize| self.total[*i] != 0.0 || self.first_order[*i] != 0.0;
        let n = self.n_bins().min(self.first_order.len());
        let Some(first) = (0..n).find(nz) else {
            self.total = Vec::new();
            self.first_order = Vec::new();
            return 0;
        };
        let last = (0..n).rev().find(nz).unwrap_or(first);
        for v in [&mut self.total, &mut self.first_order] {
            v.truncate(last + 1);
            v.drain(..first);
            v.shrink_to_fit();
        }
        self.t0_ns += first as f64 * self.dt_ns;
        first
    }

    /// The inverse of [`Waveform::trim`]: this waveform placed on the axis of `n_bins` bins
    /// starting at `t0_ns` (same `dt_ns`; `t0_ns` must lie a whole number of bins before
    /// this one's), zero elsewhere; bins falling outside the axis are dropped.
    pub fn padded_to(&self, t0_ns: f64, n_bins: usize) -> Waveform {
        let mut out = Waveform::zeros(t0_ns, self.dt_ns, n_bins);
        if self.is_empty() {
            return out;
        }
        let off = ((self.t0_ns - t0_ns) / self.dt_ns).round();
        let off = if off.is_finite() && off > 0.0 {
            off as usize
        } else {
            0
        };
        let end = (off + self.n_bins()).min(n_bins);
        if end > off {
            out.total[off..end].copy_from_slice(&self.total[..end - off]);
            out.first_order[off..end].copy_from_slice(&self.first_order[..end - off]);
        }
        out
    }

    /// Adds this waveform convolved with the pulse `kernel` (no receiver response) to `out`,
    /// placed as [`Waveform::padded_to`] places it on `out`'s axis, and returns the range of
    /// `out`'s bins it reached. On an `out` of zeros this is
    /// `convolve_kernel(kernel, None)?.padded_to(out.t0_ns, out.n_bins())` bit for bit, without
    /// the two allocations; a LiDAR run reuses `out` from pulse to pulse, clearing the range.
    /// `out.dt_ns` must equal this waveform's.
    pub fn convolve_into(
        &self,
        kernel: &PulseKernel,
        out: &mut Waveform,
    ) -> Result<std::ops::Range<usize>, LidarError> {
        self.validate()?;
        if out.dt_ns != self.dt_ns || out.total.len() != out.first_order.len() {
            return Err(LidarError::InvalidInput(
                "convolution target has another bin width or unequal channels".into(),
            ));
        }
        if self.is_empty() {
            return Ok(0..0);
        }
        let t0 = self.t0_ns - kernel.centre as f64 * self.dt_ns;
        let off = ((t0 - out.t0_ns) / self.dt_ns).round();
        let off = if off.is_finite() && off > 0.0 {
            off as usize
        } else {
            0
        };
        let n = out.n_bins();
        let end = off
            .saturating_add(self.n_bins() + kernel.weights.len() - 1)
            .min(n);
        if end <= off {
            return Ok(0..0);
        }
        convolve_add(&self.total, &kernel.weights, &mut out.total[off..end]);
        convolve_add(
            &self.first_order,
            &kernel.weights,
            &mut out.first_order[off..end],
        );
        Ok(off..end)
    }

    /// What [`Waveform::trim`] leaves of this waveform when every bin outside `range` is zero
    /// (the same values and `t0_ns` bit for bit), as a new waveform: only `range` is read.
    pub fn trimmed_within(&self, range: std::ops::Range<usize>) -> Waveform {
        let nz = |i: &usize| self.total[*i] != 0.0 || self.first_order[*i] != 0.0;
        let n = self.n_bins().min(self.first_order.len());
        let range = range.start.min(n)..range.end.min(n);
        let mut w = Waveform {
            t0_ns: self.t0_ns,
            dt_ns: self.dt_ns,
            total: Vec::new(),
            first_order: Vec::new(),
        };
        if let Some(first) = range.clone().find(nz) {
            let last = range.rev().find(nz).unwrap_or(first);
            w.total = self.total[first..=last].to_vec();
            w.first_order = self.first_order[first..=last].to_vec();
            w.t0_ns += first as f64 * self.dt_ns;
        }
        w
    }

    /// Centre time of bin `i` (ns).
    pub fn bin_centre_ns(&self, i: usize) -> f64 {
        self.t0_ns + (i as f64 + 0.5) * self.dt_ns
    }

    /// Total received energy (J), compensated sum.
    pub fn total_energy_j(&self) -> f64 {
        compensated_sum(&self.total)
    }

    /// First-order received energy (J), compensated sum.
    pub fn first_order_energy_j(&self) -> f64 {
        compensated_sum(&self.first_order)
    }

    /// Checks the waveform: finite `t0_ns`, finite `dt_ns > 0`, equal lengths, and finite
    /// non-negative energies.
    pub fn validate(&self) -> Result<(), LidarError> {
        if !self.t0_ns.is_finite() {
            return Err(LidarError::InvalidParameter {
                name: "t0_ns",
                value: self.t0_ns,
                reason: "must be finite",
            });
        }
        check_positive("dt_ns", self.dt_ns)?;
        if self.total.len() != self.first_order.len() {
            return Err(LidarError::InvalidInput(format!(
                "waveform has {} total bins but {} first-order bins",
                self.total.len(),
                self.first_order.len()
            )));
        }
        for (name, v) in [("total", &self.total), ("first_order", &self.first_order)] {
            if let Some((i, x)) = v
                .iter()
                .enumerate()
                .find(|(_, x)| !(x.is_finite() && **x >= 0.0))
            {
                return Err(LidarError::InvalidInput(format!(
                    "waveform {name}[{i}] = {x}: energies must be finite and >= 0"
                )));
            }
        }
        Ok(())
    }

    /// Convolves both channels with the emitted pulse and, optionally, a receiver impulse
    /// response: `P = E_bin ⊗ s ⊗ h_rx` (physics.md §9.4).
    ///
    /// * The pulse kernel is [`PulseShape::kernel`] (bin-integrated, unit sum), centred: no
    ///   time shift.
    /// * `receiver_response`: causal impulse response sampled on the same bins (index 0 = zero
    ///   delay), any positive scale — it is normalised to unit sum here; entries must be finite
    ///   and ≥ 0 with a positive sum.
    ///
    /// The output axis is extended (earlier `t0_ns`, more bins) so that no energy leaves it:
    /// area is preserved exactly up to rounding. An empty waveform gives an empty waveform.
    pub fn convolve(
        &self,
        pulse: &PulseShape,
        receiver_response: Option<&[f64]>,
    ) -> Result<Waveform, LidarError> {
        self.validate()?;
        if self.is_empty() {
            return Ok(self.clone());
        }
        self.convolve_valid(&pulse.kernel(self.dt_ns)?, receiver_response)
    }

    /// [`Waveform::convolve`] with the pulse's kernel on this waveform's bins computed by the
    /// caller ([`PulseShape::kernel`] of `dt_ns`, the same for every pulse of an instrument).
    pub fn convolve_kernel(
        &self,
        kernel: &PulseKernel,
        receiver_response: Option<&[f64]>,
    ) -> Result<Waveform, LidarError> {
        self.validate()?;
        if self.is_empty() {
            return Ok(self.clone());
        }
        self.convolve_valid(kernel, receiver_response)
    }

    /// The convolution of [`Waveform::convolve_kernel`] on a validated, non-empty waveform.
    fn convolve_valid(
        &self,
        kernel: &PulseKernel,
        receiver_response: Option<&[f64]>,
    ) -> Result<Waveform, LidarError> {
        let mut total = convolve_full(&self.total, &kernel.weights);
        let mut first = convolve_full(&self.first_order, &kernel.weights);
        let t0 = self.t0_ns - kernel.centre as f64 * self.dt_ns;
        if let Some(h) = receiver_response {
            if h.is_empty() {
                return Err(LidarError::InvalidInput(
                    "receiver response is empty".into(),
                ));
            }
            if let Some((i, x)) = h
                .iter()
                .enumerate()
                .find(|(_, x)| !(x.is_finite() && **x >= 0.0))
            {
                return Err(LidarError::InvalidInput(format!(
                    "receiver response[{i}] = {x}: must be finite and >= 0"
                )));
            }
            let s = compensated_sum(h);
            if !(s > 0.0) {
                return Err(LidarError::InvalidInput(
                    "receiver response has zero sum".into(),
                ));
            }
            let hn: Vec<f64> = h.iter().map(|x| x / s).collect();
            total = convolve_full(&total, &hn);
            first = convolve_full(&first, &hn);
        }
        Ok(Waveform {
            t0_ns: t0,
            dt_ns: self.dt_ns,
            total,
            first_order: first,
        })
    }
}

/// Full discrete convolution (length `a.len() + k.len() − 1`).
fn convolve_full(a: &[f64], k: &[f64]) -> Vec<f64> {
    let mut out = vec![0.0; a.len() + k.len() - 1];
    convolve_add(a, k, &mut out);
    out
}

/// Adds the full discrete convolution of `a` and `k` to `out` (bin `i + j` gets `a_i k_j`, in
/// the order of `i`), dropping the bins beyond `out`.
fn convolve_add(a: &[f64], k: &[f64], out: &mut [f64]) {
    for (i, &x) in a.iter().enumerate() {
        if x == 0.0 {
            continue;
        }
        let Some(o) = out.get_mut(i..) else { break };
        // (Zipped slices: no index check per term, and the terms of one `x` vectorise; each
        // bin still gets its terms one by one in the order of `i`.)
        for (o, &w) in o.iter_mut().zip(k) {
            *o += x * w;
        }
    }
}

/// What [`WaveformBinner::add`] did with a packet.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BinOutcome {
    /// Added to this bin.
    Binned(usize),
    /// Arrived before the gate opens (booked in [`GateLosses::before_j`]).
    BeforeGate,
    /// Arrived after the gate closes (booked in [`GateLosses::after_j`]).
    AfterGate,
    /// Rejected: NaN path, or energy NaN/infinite/negative (counted in [`GateLosses::rejected`]).
    Rejected,
}

/// Energy received outside the gate, and packets rejected as invalid.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct GateLosses {
    /// All-order energy arriving before the gate (J).
    pub before_j: f64,
    /// All-order energy arriving after the gate (J).
    pub after_j: f64,
    /// First-order energy arriving before the gate (J).
    pub first_order_before_j: f64,
    /// First-order energy arriving after the gate (J).
    pub first_order_after_j: f64,
    /// Number of rejected packets (invalid path or energy); their energy is not booked.
    pub rejected: u64,
}

/// Accumulates received packets into path-length bins (physics.md §9.4), with compensated
/// (Neumaier) sums so that 1e9 packets of 1e-13 J keep full precision. Energy outside the gate
/// is booked separately, never dropped silently. For parallel tracking use one binner per
/// thread and [`WaveformBinner::merge`].
#[derive(Debug, Clone, PartialEq)]
pub struct WaveformBinner {
    path_min_m: f64,
    bin_len_m: f64,
    dt_ns: f64,
    /// Orders other than 1 (0 = direct emitter→receiver, ≥ 2 = multiple scattering); the total
    /// of a bin is `first + rest` (one rounding), so a first-order packet costs one compensated
    /// add, not two (the whole-bin loop of the LiDAR first-order estimate adds ~900 per pulse).
    rest: Vec<NeumaierSum>,
    first: Vec<NeumaierSum>,
    before: NeumaierSum,
    after: NeumaierSum,
    first_before: NeumaierSum,
    first_after: NeumaierSum,
    rejected: u64,
    /// Bins `[dirty.0, dirty.1)` hold every bin that may differ from zero (empty: `(n, 0)`), so
    /// that [`WaveformBinner::take_trimmed`] reads and resets only the bins a pulse touched, not
    /// the whole gate (a LiDAR run reuses one binner for the pulses of a thread).
    dirty: (usize, usize),
}

/// Whether an energy packet (J) can be binned: finite and ≥ 0 (−0 included). The same as
/// `e.is_finite() && e >= 0.0` for every value, NaN included, on the bits: +0 up to the
/// largest finite value, or −0. (LLVM turns the float form, and `0 ≤ e < ∞`, into a class
/// test of ~20 integer instructions on x86-64 without SSE4.1, paid per packet in the
/// binning loops.)
#[inline(always)]
pub fn bookable(e: f64) -> bool {
    let b = e.to_bits();
    b < 0x7FF0_0000_0000_0000 || b == 0x8000_0000_0000_0000
}

impl WaveformBinner {
    /// Gate from path length `path_min_m` to `path_max_m` (m, two-way path, `path_min_m ≥ 0`,
    /// `path_max_m > path_min_m`) with bins of `dt_ns` (ns). The bin count is
    /// `ceil((path_max − path_min)/(cΔt))`, so the gate ends at or just after `path_max_m`.
    /// DART's gate is `[2(d_min − r_above), 2(d_min + r_below)]` (physics.md §9.1).
    pub fn new(path_min_m: f64, path_max_m: f64, dt_ns: f64) -> Result<Self, LidarError> {
        check_non_negative("path_min_m", path_min_m)?;
        check_positive("dt_ns", dt_ns)?;
        if !(path_max_m.is_finite() && path_max_m > path_min_m) {
            return Err(LidarError::InvalidParameter {
                name: "path_max_m",
                value: path_max_m,
                reason: "must be finite and > path_min_m",
            });
        }
        let bin_len_m = path_m_from_time_ns(dt_ns);
        let nf = ((path_max_m - path_min_m) / bin_len_m * (1.0 - 4.0 * f64::EPSILON)).ceil();
        if !(nf >= 1.0 && nf <= MAX_BINS as f64) {
            return Err(LidarError::InvalidInput(format!(
                "gate [{path_min_m}, {path_max_m}] m with dt = {dt_ns} ns needs {nf} bins (max {MAX_BINS})"
            )));
        }
        let n = nf as usize;
        Ok(Self {
            path_min_m,
            bin_len_m,
            dt_ns,
            rest: vec![NeumaierSum::default(); n],
            first: vec![NeumaierSum::default(); n],
            before: NeumaierSum::default(),
            after: NeumaierSum::default(),
            first_before: NeumaierSum::default(),
            first_after: NeumaierSum::default(),
            rejected: 0,
            dirty: (n, 0),
        })
    }

    /// Widens the dirty range to bins `[lo, hi)`.
    #[inline(always)]
    fn touch(&mut self, lo: usize, hi: usize) {
        self.dirty = (self.dirty.0.min(lo), self.dirty.1.max(hi));
    }

    /// Number of bins.
    pub fn n_bins(&self) -> usize {
        self.first.len()
    }

    /// Gate start time (ns).
    pub fn t0_ns(&self) -> f64 {
        time_ns_from_path_m(self.path_min_m)
    }

    /// Bin width (ns).
    pub fn dt_ns(&self) -> f64 {
        self.dt_ns
    }

    /// Bin length in path units, `cΔt` (m).
    pub fn bin_len_m(&self) -> f64 {
        self.bin_len_m
    }

    /// Path length (m) of the start of bin `i` (`i = n_bins` gives the gate end).
    pub fn bin_start_path_m(&self, i: usize) -> f64 {
        self.path_min_m + i as f64 * self.bin_len_m
    }

    /// Bin holding path length `path_m`, `Err(BinOutcome)` if outside the gate or NaN.
    /// Rule: `i = floor((L − L_min)/(cΔt))`.
    pub fn bin_index(&self, path_m: f64) -> Result<usize, BinOutcome> {
        if path_m.is_nan() {
            return Err(BinOutcome::Rejected);
        }
        let x = (path_m - self.path_min_m) / self.bin_len_m;
        if x < 0.0 {
            Err(BinOutcome::BeforeGate)
        } else if x >= self.first.len() as f64 {
            Err(BinOutcome::AfterGate)
        } else {
            // x ≥ 0: truncation is the floor (no libm call).
            Ok((x as usize).min(self.first.len() - 1))
        }
    }

    /// Adds a first-order packet of `energy_j` (J) to bin `i` (known to the caller, e.g. a
    /// stratum that is one bin); rejected (counted) if `i` is outside the gate or the energy
    /// is not finite and ≥ 0.
    #[inline]
    pub fn add_first_order_at(&mut self, i: usize, energy_j: f64) {
        if !bookable(energy_j) || i >= self.first.len() {
            self.rejected += 1;
            return;
        }
        self.first[i].add(energy_j);
        self.touch(i, i + 1);
    }

    /// The first-order bins, for a caller that adds many packets to known bins after its own
    /// checks (energies finite and ≥ 0; [`WaveformBinner::reject`] for the others), as
    /// [`WaveformBinner::add_first_order_at`] does one at a time. The caller then reports the
    /// bins it wrote with [`WaveformBinner::mark_written`] (once per batch: marking in the loop
    /// cost ~40 instructions per call of the LiDAR first-order binning, 5k per pulse).
    #[inline]
    pub fn first_order_bins_mut(&mut self) -> &mut [NeumaierSum] {
        &mut self.first
    }

    /// Records that bins `[lo, hi)` may have been written through
    /// [`WaveformBinner::first_order_bins_mut`], so that [`WaveformBinner::take_trimmed`]
    /// reads and resets them.
    #[inline]
    pub fn mark_written(&mut self, lo: usize, hi: usize) {
        self.touch(lo, hi);
    }

    /// Counts `n` packets rejected by a caller of [`WaveformBinner::first_order_bins_mut`].
    #[inline]
    pub fn reject(&mut self, n: u64) {
        self.rejected += n;
    }

    /// Adds a packet of `energy_j` (J) that travelled `path_length_m` (m) after `order`
    /// scattering events (1 = single scattering; 0 is accepted for a direct emitter→receiver
    /// path and counted in the total only). Hot-loop method: never fails, reports what it did.
    pub fn add(&mut self, path_length_m: f64, energy_j: f64, order: u32) -> BinOutcome {
        if !bookable(energy_j) {
            self.rejected += 1;
            return BinOutcome::Rejected;
        }
        let first = order == 1;
        match self.bin_index(path_length_m) {
            Ok(i) => {
                if first {
                    self.first[i].add(energy_j);
                } else {
                    self.rest[i].add(energy_j);
                }
                self.touch(i, i + 1);
                BinOutcome::Binned(i)
            }
            Err(BinOutcome::BeforeGate) => {
                self.before.add(energy_j);
                if first {
                    self.first_before.add(energy_j);
                }
                BinOutcome::BeforeGate
            }
            Err(BinOutcome::AfterGate) => {
                self.after.add(energy_j);
                if first {
                    self.first_after.add(energy_j);
                }
                BinOutcome::AfterGate
            }
            Err(other) => {
                self.rejected += 1;
                other
            }
        }
    }

    /// Adds another binner's tallies (same gate required).
    pub fn merge(&mut self, other: &WaveformBinner) -> Result<(), LidarError> {
        if other.path_min_m != self.path_min_m
            || other.dt_ns != self.dt_ns
            || other.first.len() != self.first.len()
        {
            return Err(LidarError::InvalidInput(
                "cannot merge waveform binners with different gates".into(),
            ));
        }
        for (a, b) in self.rest.iter_mut().zip(&other.rest) {
            a.merge(b);
        }
        for (a, b) in self.first.iter_mut().zip(&other.first) {
            a.merge(b);
        }
        self.before.merge(&other.before);
        self.after.merge(&other.after);
        self.first_before.merge(&other.first_before);
        self.first_after.merge(&other.first_after);
        self.rejected += other.rejected;
        self.touch(other.dirty.0, other.dirty.1);
        Ok(())
    }

    /// Energy outside the gate and rejected packets so far.
    pub fn losses(&self) -> GateLosses {
        GateLosses {
            before_j: self.before.value(),
            after_j: self.after.value(),
            first_order_before_j: self.first_before.value(),
            first_order_after_j: self.first_after.value(),
            rejected: self.rejected,
        }
    }

    /// The binned waveform (not convolved).
    pub fn waveform(&self) -> Waveform {
        Waveform {
            t0_ns: self.t0_ns(),
            dt_ns: self.dt_ns,
            total: self
                .first
                .iter()
                .zip(&self.rest)
                .map(|(f, r)| f.value() + r.value())
                .collect(),
            first_order: self.first.iter().map(NeumaierSum::value).collect(),
        }
    }

    /// `waveform()` then [`Waveform::trim`] (the same values and `t0_ns` bit for bit) and the
    /// gate losses, and the binner reset to its state after [`WaveformBinner::new`]: only the
    /// bins a packet reached are read and cleared (a LiDAR pulse reaches a few tens of the
    /// gate's bins; allocating, zeroing and trimming the whole gate cost ~20k instructions per
    /// pulse on the forest bench).
    pub fn take_trimmed(&mut self) -> (Waveform, GateLosses) {
        let losses = self.losses();
        let (lo, hi) = self.dirty;
        debug_assert!(
            [&self.first, &self.rest].iter().all(|v| {
                let (a, b) = (lo.min(v.len()), hi.clamp(lo.min(v.len()), v.len()));
                v[..a]
                    .iter()
                    .chain(&v[b..])
                    .all(|x| *x == NeumaierSum::default())
            }),
            "a bin outside the marked range was written"
        );
        let total = |i: usize| self.first[i].value() + self.rest[i].value();
        let nz = |i: &usize| total(*i) != 0.0 || self.first[*i].value() != 0.0;
        let mut w = Waveform {
            t0_ns: self.t0_ns(),
            dt_ns: self.dt_ns,
            total: Vec::new(),
            first_order: Vec::new(),
        };
        if let Some(first) = (lo..hi).find(nz) {
            let last = (lo..hi).rev().find(nz).unwrap_or(first);
            w.total = (first..=last).map(total).collect();
            w.first_order = self.first[first..=last]
                .iter()
                .map(NeumaierSum::value)
                .collect();
            w.t0_ns += first as f64 * self.dt_ns;
        }
        if lo < hi {
            self.first[lo..hi].fill(NeumaierSum::default());
            self.rest[lo..hi].fill(NeumaierSum::default());
        }
        self.dirty = (self.first.len(), 0);
        self.before = NeumaierSum::default();
        self.after = NeumaierSum::default();
        self.first_before = NeumaierSum::default();
        self.first_after = NeumaierSum::default();
        self.rejected = 0;
        (w, losses)
    }
}

/// Gap correlation between the downward and upward paths of the analytic first-order waveform
/// (physics.md §9.6).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum GapCorrelation {
    /// Pure turbid medium: independent gaps down and up, two-way transmittance
    /// `e^{−2G u_f (r−r_t)}`.
    Independent,
    /// Monostatic hotspot with finite leaves: the return goes back through the same gap,
    /// one-way transmittance `e^{−G u_f (r−r_t)}`.
    Correlated,
}

/// Nadir LiDAR over a horizontally homogeneous turbid canopy layer on a Lambertian ground, no
/// atmosphere, receiver FOV containing the whole footprint (physics.md §9.6).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FirstOrderCanopy {
    /// Emitted pulse energy E_0 (J).
    pub pulse_energy_j: f64,
    /// Receiver aperture area A (m²).
    pub aperture_m2: f64,
    /// Range R from the sensor to the canopy top r_t (m). The geometric factor A/R² is held at
    /// this range across the canopy (R ≫ h, as in §9.6).
    pub range_top_m: f64,
    /// Canopy thickness h (m); `r_g = r_t + h`. May be 0 only when `lai` is 0.
    pub height_m: f64,
    /// Leaf area index (m² m⁻²); leaf volume density `u_f = LAI/h`.
    pub lai: f64,
    /// Ross G-function in the (nadir) beam direction (0.5 for a spherical LAD, 1 for
    /// horizontal leaves).
    pub g_function: f64,
    /// Area backscatter phase function Γ(π) (ρ_L/3 for spherical bi-Lambertian leaves, ρ_L for
    /// horizontal leaves; §3.3).
    pub gamma_backscatter: f64,
    /// Lambertian ground reflectance ρ_g.
    pub rho_ground: f64,
    /// Independent (turbid) or correlated (hotspot) gaps.
    pub correlation: GapCorrelation,
}

/// Analytic first-order waveform, binned, with its exact integrals.
#[derive(Debug, Clone, PartialEq)]
pub struct AnalyticFirstOrder {
    /// Binned energies (J); `total` equals `first_order` (single scattering only).
    pub waveform: Waveform,
    /// Integrated canopy return E_c (J), whole canopy, regardless of the gate.
    pub canopy_energy_j: f64,
    /// Integrated ground return E_g (J), regardless of the gate.
    pub ground_energy_j: f64,
    /// Part of E_c + E_g outside the gate (J).
    pub out_of_gate_j: f64,
}

/// First-order waveform of physics.md §9.6, integrated exactly over each bin (the canopy term
/// is an exponential in range, the ground a Dirac at `r_g`):
///
/// `dE/dr = E_0 (A/R²)[(u_f Γ_π/π) e^{−k u_f (r−r_t)} 1_{[r_t,r_g)}(r) + (ρ_g/π) e^{−k·LAI} δ(r−r_g)]`
///
/// with k = 2G ([`GapCorrelation::Independent`]) or k = G ([`GapCorrelation::Correlated`]).
/// Integrals: `E_c = E_0 (A/R²) Γ_π (1 − e^{−k·LAI})/(πk)`, `E_g = E_0 (A/R²)(ρ_g/π)e^{−k·LAI}`.
/// The bins are those of `WaveformBinner::new(path_min_m, path_max_m, dt_ns)` (path `L = 2r`;
/// the ground Dirac goes to the bin holding `2 r_g` by the binner's rule). The result is not
/// convolved: use [`Waveform::convolve`].
pub fn analytic_first_order(
    p: &FirstOrderCanopy,
    path_min_m: f64,
    path_max_m: f64,
    dt_ns: f64,
) -> Result<AnalyticFirstOrder, LidarError> {
    check_non_negative("pulse_energy_j", p.pulse_energy_j)?;
    check_non_negative("aperture_m2", p.aperture_m2)?;
    check_positive("range_top_m", p.range_top_m)?;
    check_non_negative("height_m", p.height_m)?;
    check_non_negative("lai", p.lai)?;
    check_positive("g_function", p.g_function)?;
    check_non_negative("gamma_backscatter", p.gamma_backscatter)?;
    check_unit_interval("rho_ground", p.rho_ground)?;
    if p.lai > 0.0 && p.height_m <= 0.0 {
        return Err(LidarError::InvalidParameter {
            name: "height_m",
            value: p.height_m,
            reason: "must be > 0 when lai > 0",
        });
    }
    let binner = WaveformBinner::new(path_min_m, path_max_m, dt_ns)?;
    let n = binner.n_bins();
    let c = p.pulse_energy_j * p.aperture_m2 / (p.range_top_m * p.range_top_m);
    let k = match p.correlation {
        GapCorrelation::Independent => 2.0 * p.g_function,
        GapCorrelation::Correlated => p.g_function,
    };
    let r_t = p.range_top_m;
    let r_g = r_t + p.height_m;
    // Canopy: energy between ranges a < b inside [r_t, r_g] is
    // C Γ/(πk) [e^{-k u (a−r_t)} − e^{-k u (b−r_t)}] = C Γ/(πk) e^{-x_a}(−expm1(−(x_b−x_a))).
    let canopy_coef = c * p.gamma_backscatter / (PI * k);
    let optical = |r: f64| -> f64 {
        if p.lai > 0.0 {
            k * p.lai * ((r - r_t) / p.height_m).clamp(0.0, 1.0)
        } else {
            0.0
        }
    };
    let canopy_between = |a: f64, b: f64| -> f64 {
        let a = a.max(r_t);
        let b = b.min(r_g);
        if !(b > a) || p.lai == 0.0 {
            return 0.0;
        }
        let xa = optical(a);
        let xb = optical(b);
        canopy_coef * (-xa).exp() * (-(-(xb - xa)).exp_m1())
    };
    let canopy_energy_j = if p.lai > 0.0 {
        canopy_coef * (-(-k * p.lai).exp_m1())
    } else {
        0.0
    };
    let ground_energy_j = c * p.rho_ground / PI * (-k * p.lai).exp();

    let mut w = Waveform::zeros(binner.t0_ns(), dt_ns, n);
    let mut inside = NeumaierSum::default();
    for i in 0..n {
        let e = canopy_between(
            0.5 * binner.bin_start_path_m(i),
            0.5 * binner.bin_start_path_m(i + 1),
        );
        w.total[i] = e;
        inside.add(e);
    }
    if let Ok(i) = binner.bin_index(2.0 * r_g) {
        w.total[i] += ground_energy_j;
        inside.add(ground_energy_j);
    }
    w.first_order = w.total.clone();
    let out_of_gate_j = (canopy_energy_j + ground_energy_j - inside.value()).max(0.0);
    Ok(AnalyticFirstOrder {
        waveform: w,
        canopy_energy_j,
        ground_energy_j,
        out_of_gate_j,
    })
}

/// Energy (J) returned by a bare Lambertian ground of reflectance `rho_ground` lit by the whole
/// pulse `pulse_energy_j` (J), seen by an aperture `aperture_m2` (m²) at range `range_m` (m):
/// `E = E_0 (A/R²)(ρ_g/π) cos θ_v` (physics.md §13 item 12). `cos_view` is the cosine between
/// the ground normal and the direction to the receiver (1 at nadir over flat ground); the cosine
/// of incidence cancels against the footprint area (`S_fp/cos θ` lit by `E_0`).
pub fn bare_ground_energy_j(
    pulse_energy_j: f64,
    aperture_m2: f64,
    range_m: f64,
    rho_ground: f64,
    cos_view: f64,
) -> Result<f64, LidarError> {
    check_non_negative("pulse_energy_j", pulse_energy_j)?;
    check_non_negative("aperture_m2", aperture_m2)?;
    check_positive("range_m", range_m)?;
    check_unit_interval("rho_ground", rho_ground)?;
    check_unit_interval("cos_view", cos_view)?;
    Ok(pulse_energy_j * aperture_m2 / (range_m * range_m) * rho_ground / PI * cos_view)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `bookable` accepts exactly the values `is_finite() && ≥ 0` accepts (a packet test in
    /// the binning loops; the products must not change).
    #[test]
    fn bookable_is_finite_and_non_negative() {
        for e in [
            0.0,
            -0.0,
            5e-324,
            -5e-324,
            f64::MIN_POSITIVE,
            1.0,
            -1.0,
            f64::MAX,
            f64::MIN,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NAN,
            -f64::NAN,
        ] {
            assert_eq!(bookable(e), e.is_finite() && e >= 0.0, "{e:e}");
        }
    }

    /// Trimming keeps every non-zero bin at its time and the energies bit for bit; convolving a
    /// trimmed waveform gives the trimmed convolution of the full one.
    #[test]
    fn trim_keeps_values_times_and_energy() {
        let mut w = Waveform::zeros(100.0, 0.5, 40);
        w.total[7] = 1e-13;
        w.total[12] = 3.0;
        w.first_order[5] = 2e-300;
        w.total[30] = 0.25;
        let full = w.clone();
        let first = w.trim();
        assert_eq!((first, w.n_bins(), w.first_order.len()), (5, 26, 26));
        for i in 0..w.n_bins() {
            assert_eq!(w.total[i].to_bits(), full.total[i + first].to_bits());
            assert_eq!(w.first_order[i], full.first_order[i + first]);
            assert!((w.bin_centre_ns(i) - full.bin_centre_ns(i + first)).abs() < 1e-12);
        }
        assert_eq!(w.total_energy_j(), full.total_energy_j());
        assert_eq!(w.first_order_energy_j(), full.first_order_energy_j());
        assert_eq!(w.trim(), 0);
        let shape = crate::lidar::pulse::PulseShape::from_fwhm_ns(2.0, 3.0).unwrap();
        let mut a = full.convolve(&shape, None).unwrap();
        let off = a.trim();
        let b = w.convolve(&shape, None).unwrap();
        assert_eq!(a.n_bins(), b.n_bins());
        assert!((a.t0_ns - b.t0_ns).abs() < 1e-12 && off > 0);
        assert_eq!(a.total, b.total);
        assert_eq!(a.first_order, b.first_order);
        let back = w.padded_to(full.t0_ns, full.n_bins());
        assert_eq!(back, full);
        let mut z = Waveform::zeros(3.0, 1.0, 9);
        assert_eq!(z.trim(), 0);
        assert!(z.is_empty() && z.first_order.is_empty() && z.t0_ns == 3.0);
    }

    #[test]
    fn binner_rules() {
        let mut b = WaveformBinner::new(100.0, 130.0, 1.0).unwrap();
        let bl = b.bin_len_m();
        assert_eq!(b.n_bins(), (30.0 / bl).ceil() as usize);
        assert_eq!(b.add(100.0, 1.0, 1), BinOutcome::Binned(0));
        assert_eq!(b.add(100.0 + 1.5 * bl, 2.0, 2), BinOutcome::Binned(1));
        assert_eq!(b.add(99.0, 3.0, 1), BinOutcome::BeforeGate);
        assert_eq!(b.add(1e9, 4.0, 1), BinOutcome::AfterGate);
        assert_eq!(b.add(f64::INFINITY, 5.0, 3), BinOutcome::AfterGate);
        assert_eq!(b.add(f64::NAN, 1.0, 1), BinOutcome::Rejected);
        assert_eq!(b.add(110.0, -1.0, 1), BinOutcome::Rejected);
        assert_eq!(b.add(110.0, f64::NAN, 1), BinOutcome::Rejected);
        let l = b.losses();
        assert_eq!((l.before_j, l.after_j, l.rejected), (3.0, 9.0, 3));
        assert_eq!((l.first_order_before_j, l.first_order_after_j), (3.0, 4.0));
        let w = b.waveform();
        assert_eq!(w.total[0], 1.0);
        assert_eq!(w.total[1], 2.0);
        assert_eq!(w.first_order[1], 0.0);
        assert!((w.t0_ns - 100.0 / SPEED_OF_LIGHT_M_PER_S * 1e9).abs() < 1e-12);
        assert!(WaveformBinner::new(10.0, 10.0, 1.0).is_err());
        assert!(WaveformBinner::new(0.0, 1e12, 1e-3).is_err());
        assert!(WaveformBinner::new(0.0, 10.0, f64::NAN).is_err());
    }

    #[test]
    fn merge_adds_tallies() {
        let mut a = WaveformBinner::new(0.0, 10.0, 1.0).unwrap();
        let mut b = a.clone();
        a.add(1.0, 1.0, 1);
        b.add(1.0, 2.0, 2);
        b.add(-1.0, 0.5, 1);
        a.merge(&b).unwrap();
        let w = a.waveform();
        assert_eq!(w.total[3], 3.0);
        assert_eq!(w.first_order[3], 1.0);
        assert_eq!(a.losses().before_j, 0.5);
        let c = WaveformBinner::new(0.0, 20.0, 1.0).unwrap();
        assert!(a.merge(&c).is_err());
    }

    #[test]
    fn waveform_validation() {
        let mut w = Waveform::zeros(0.0, 1.0, 3);
        assert!(w.validate().is_ok());
        w.total[1] = f64::NAN;
        assert!(w.validate().is_err());
        w.total[1] = -1.0;
        assert!(w.validate().is_err());
        let w2 = Waveform {
            t0_ns: 0.0,
            dt_ns: 1.0,
            total: vec![0.0; 2],
            first_order: vec![],
        };
        assert!(w2.validate().is_err());
        let p = PulseShape::from_fwhm_ns(3.0, 3.0).unwrap();
        let empty = Waveform::zeros(0.0, 1.0, 0);
        assert!(empty.convolve(&p, None).unwrap().is_empty());
        let z = Waveform::zeros(0.0, 1.0, 4);
        assert!(z.convolve(&p, Some(&[])).is_err());
        assert!(z.convolve(&p, Some(&[0.0, 0.0])).is_err());
        assert!(z.convolve(&p, Some(&[1.0, f64::NAN])).is_err());
    }

    #[test]
    fn bare_ground() {
        let e = bare_ground_energy_j(1.0, 0.1, 1000.0, 0.3, 1.0).unwrap();
        assert!((e - 0.1 / 1e6 * 0.3 / PI).abs() < 1e-22);
        assert!(bare_ground_energy_j(1.0, 0.1, 0.0, 0.3, 1.0).is_err());
        assert!(bare_ground_energy_j(1.0, 0.1, 10.0, 1.3, 1.0).is_err());
    }
}
