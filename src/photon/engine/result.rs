//! What the photon engine returns (DART 5 paper §4): per-element tallies with their per-batch
//! estimates ([`PhotonResult`]), the layout of the summary tallies ([`Summary`]) and the
//! standard error of a sum of batch estimates.

/// What the engine computed; per-element arrays hold `n_channels` values per element.
#[derive(Debug, Clone, Default)]
pub struct PhotonResult {
    /// Channels (bands × (1 + sky)).
    pub n_channels: usize,
    /// Bands.
    pub n_bands: usize,
    /// Whether sky channels exist.
    pub has_sky: bool,
    /// A thermal run (issue #34): channels `[sun (zero), thermal]`.
    pub has_thermal: bool,
    /// Thermal run: the sky's power through the top per band (part of the thermal
    /// channels' `source`), W.
    pub thermal_sky_source: Vec<f64>,
    /// Source power per channel, W.
    pub source: Vec<f64>,
    /// Escaped power per tiling direction `[dir][channel]`, W (escape counting).
    pub escaped: Vec<f64>,
    /// Peel-off intensity toward each view `[view][channel]`, W sr⁻¹.
    pub peel: Vec<f64>,
    /// Absorbed per turbid entry, W.
    pub absorbed_turbid: Vec<f64>,
    /// Intercepted (collided) per turbid entry, W.
    pub intercepted_turbid: Vec<f64>,
    /// Absorbed per facet, W.
    pub absorbed_facet: Vec<f64>,
    /// Intercepted per facet, W.
    pub intercepted_facet: Vec<f64>,
    /// Absorbed by the flat ground per column, W.
    pub absorbed_ground: Vec<f64>,
    /// Intercepted by the flat ground per column, W.
    pub intercepted_ground: Vec<f64>,
    /// Absorbed by fluids per cell that holds one (`[cell][channel]`, sparse: cell ids in
    /// `fluid_cells`), W.
    pub absorbed_fluid: Vec<f64>,
    /// Cells of `absorbed_fluid`.
    pub fluid_cells: Vec<u32>,
    /// Lost (isolated sides, bottom leaks, order/crossing caps), W.
    pub lost: Vec<f64>,
    /// Russian-roulette balance (killed minus added weight; expectation 0), W.
    pub roulette: Vec<f64>,
    /// Per-batch summaries (see [`Summary`]), for standard errors.
    pub batch_summaries: Vec<Vec<f64>>,
    /// Layout of the summaries.
    pub summary: Summary,
    /// Photons traced.
    pub photons: u64,
    /// Scattering events.
    pub events: u64,
    /// Cell crossings of the flights (visited cells).
    pub crossings: u64,
    /// Empty cells the flights jumped over (empty-space skipping, not in `crossings`).
    pub skipped: u64,
    /// Frame-camera pixel radiances summed over the batches, W m⁻² sr⁻¹ (per band unit of the
    /// irradiances): the input's cameras one after the other, pixel `i + nx·j`, channel.
    pub camera: Vec<f64>,
    /// Per camera pixel and band (`[pixel][band]`, cameras one after the other): the sum over
    /// batches of the square of the batch's radiance (sun + sky channels), for the standard
    /// errors.
    pub camera_sq: Vec<f64>,
    /// Per camera and band (`[camera][band]`): the sum over batches of the square of the
    /// batch's image-mean radiance (sun + sky channels), for the standard error of the mean.
    pub camera_mean_sq: Vec<f64>,
}

/// Layout of a batch summary vector: per channel escaped, absorbed (vegetation, facets,
/// fluids), absorbed by the ground, intercepted by the ground; then escaped per tiling
/// direction and channel; then peel-off per view and channel. With an atmosphere
/// ([`Summary::atm_layers`] > 0) the atmosphere's tallies follow ([`Summary::toa_view`]).
#[derive(Debug, Clone, Default)]
pub struct Summary {
    /// Channels.
    pub w: usize,
    /// Tiling directions.
    pub n_dirs: usize,
    /// Views.
    pub n_views: usize,
    /// Atmosphere layers (0: no atmosphere, no atmosphere tallies).
    pub atm_layers: usize,
}

impl Summary {
    /// Length of a summary vector.
    pub fn len(&self) -> usize {
        let atm = if self.atm_layers > 0 {
            (2 * self.n_views + 5 + self.atm_layers) * self.w
        } else {
            0
        };
        4 * self.w + self.n_dirs * self.w + 4 * self.n_views * self.w + atm
    }
    /// Start of the atmosphere tallies.
    fn atm_base(&self) -> usize {
        4 * self.w + self.n_dirs * self.w + 4 * self.n_views * self.w
    }
    /// Atmosphere: index of the peel-off intensity toward view `v` at the top of the
    /// atmosphere (W sr⁻¹).
    pub fn toa_view(&self, v: usize, ch: usize) -> usize {
        self.atm_base() + v * self.w + ch
    }
    /// Atmosphere: index of the peel-off intensity at the bottom of the atmosphere travelling
    /// down along `−Ω_v` (the diffuse sky seen looking toward view `v`), W sr⁻¹.
    pub fn boa_sky(&self, v: usize, ch: usize) -> usize {
        self.atm_base() + (self.n_views + v) * self.w + ch
    }
    /// Atmosphere: index of the power escaped through the top of the atmosphere.
    pub fn toa_escaped(&self, ch: usize) -> usize {
        self.atm_base() + 2 * self.n_views * self.w + ch
    }
    /// Atmosphere: index of the power entering the scene through its top (bottom of the
    /// atmosphere, every downward crossing).
    pub fn boa_down(&self, ch: usize) -> usize {
        self.atm_base() + (2 * self.n_views + 1) * self.w + ch
    }
    /// Atmosphere: index of the unscattered (direct sun) part of [`Summary::boa_down`].
    pub fn boa_direct(&self, ch: usize) -> usize {
        self.atm_base() + (2 * self.n_views + 2) * self.w + ch
    }
    /// Atmosphere: index of the weight balance of the atmosphere (Russian roulette and the
    /// band reweighting of free paths; expectation 0).
    pub fn atm_balance(&self, ch: usize) -> usize {
        self.atm_base() + (2 * self.n_views + 3) * self.w + ch
    }
    /// Atmosphere: index of the power lost in the atmosphere (order cap, horizontal flights).
    pub fn atm_lost(&self, ch: usize) -> usize {
        self.atm_base() + (2 * self.n_views + 4) * self.w + ch
    }
    /// Atmosphere: index of the power absorbed in layer `l` (0 = lowest).
    pub fn atm_absorbed(&self, l: usize, ch: usize) -> usize {
        self.atm_base() + (2 * self.n_views + 5 + l) * self.w + ch
    }
    /// True when empty.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
    /// Index of escaped power of channel `ch`.
    pub fn escaped(&self, ch: usize) -> usize {
        ch
    }
    /// Index of non-ground absorption of channel `ch`.
    pub fn absorbed(&self, ch: usize) -> usize {
        self.w + ch
    }
    /// Index of ground absorption.
    pub fn absorbed_ground(&self, ch: usize) -> usize {
        2 * self.w + ch
    }
    /// Index of ground interception.
    pub fn ground(&self, ch: usize) -> usize {
        3 * self.w + ch
    }
    /// Index of escaped power in tiling direction `j`.
    pub fn dir(&self, j: usize, ch: usize) -> usize {
        4 * self.w + j * self.w + ch
    }
    /// Index of the peel-off intensity toward view `v`.
    pub fn view(&self, v: usize, ch: usize) -> usize {
        4 * self.w + self.n_dirs * self.w + v * self.w + ch
    }
    /// Index of a RAMI component of the peel-off toward view `v`: 0 = single scattering by
    /// the vegetation (and other non-ground elements; RAMI `co_sgl`), 1 = single scattering by
    /// the ground of light that met nothing else on the way down or up (`uc_sgl`), 2 = multiple
    /// scattering (`mlt`).
    pub fn view_component(&self, v: usize, comp: usize, ch: usize) -> usize {
        4 * self.w
            + self.n_dirs * self.w
            + self.n_views * self.w
            + (comp * self.n_views + v) * self.w
            + ch
    }
}

/// Standard error of the sum over batches of component `i`: `√(B/(B−1) Σ_k (S_k − S̄)²)`.
pub fn sum_standard_error(batches: &[Vec<f64>], i: usize) -> f64 {
    let b = batches.len();
    if b < 2 {
        return f64::NAN;
    }
    let mean = batches.iter().map(|s| s[i]).sum::<f64>() / b as f64;
    let ss: f64 = batches.iter().map(|s| (s[i] - mean).powi(2)).sum();
    (b as f64 / (b as f64 - 1.0) * ss).sqrt()
}
