//! WALKDOC

pub(in crate::radiative) mod batch;
mod one_ray;
mod simple;

use crate::radiative::engine::*;
use glam::DVec3;

impl Ctx<'_> {
    /// Traces one ray; `pw` holds the channel powers and is consumed.
    pub(in crate::radiative) fn trace(
        &self,
        p: DVec3,
        dir: usize,
        skip_facet: Option<u32>,
        pw: &mut [f64],
        out: &mut ChunkOut,
    ) {
        self.trace_any::<false>(p, dir, skip_facet, pw, out);
    }

    /// [`Ctx::trace`] for a first-order sun ray leaving its scattering point `p` along an
    /// upward direction: turbid extinction gets the hotspot correlation of [`hotspot_terms`]
    /// (the ray goes back through the gaps the sun came through).
    pub(in crate::radiative) fn trace_hotspot(
        &self,
        p: DVec3,
        dir: usize,
        skip_facet: Option<u32>,
        pw: &mut [f64],
        out: &mut ChunkOut,
    ) {
        self.trace_any::<true>(p, dir, skip_facet, pw, out);
    }

    /// Dispatches to a copy of the tracker specialised for the channel count (1, 2 or 4
    /// channels: loops over channels unrolled), with the turbid accumulators taken out of `out`
    /// for the ray's duration.
    pub(in crate::radiative) fn trace_any<const HS: bool>(
        &self,
        p: DVec3,
        dir: usize,
        skip_facet: Option<u32>,
        pw: &mut [f64],
        out: &mut ChunkOut,
    ) {
        if !HS && self.batch && matches!(out.tur.as_deref(), Some(TurAcc::Dense { .. })) {
            self.queue(p, dir, pw, out);
            return;
        }
        let mut tur = out.tur.take().expect("accumulator");
        let simple = !HS && self.simple;
        match (self.w, simple) {
            (1, true) => self.trace_simple::<1>(p, dir, pw, &mut tur, out),
            (2, true) => self.trace_simple::<2>(p, dir, pw, &mut tur, out),
            (4, true) => self.trace_simple::<4>(p, dir, pw, &mut tur, out),
            (_, true) => self.trace_simple::<0>(p, dir, pw, &mut tur, out),
            (1, false) => self.trace_w::<1, HS>(p, dir, skip_facet, pw, &mut tur, out),
            (2, false) => self.trace_w::<2, HS>(p, dir, skip_facet, pw, &mut tur, out),
            (4, false) => self.trace_w::<4, HS>(p, dir, skip_facet, pw, &mut tur, out),
            _ => self.trace_w::<0, HS>(p, dir, skip_facet, pw, &mut tur, out),
        }
        out.tur = Some(tur);
    }
}
