//! The zonal equal-solid-angle tiling of each hemisphere, its refinement (oversampled regions,
//! exact directions by sector splitting) and the [`DirectionSet`] built from it, with its
//! O(log N) lookup tree and the angular-sector partition (physics.md §2.2–2.4).

use super::*;

#[derive(Debug, Clone, Copy, PartialEq)]
struct Rect {
    u0: f64,
    u1: f64,
    phi0: f64,
    dphi: f64,
}

impl Rect {
    fn area(&self) -> f64 {
        self.dphi * (self.u1 - self.u0)
    }
    fn full_ring(&self) -> bool {
        self.dphi >= TAU - 1e-12
    }
    fn is_cap(&self) -> bool {
        self.full_ring() && self.u1 >= 1.0
    }
    fn rel_phi(&self, phi: f64) -> f64 {
        (phi - self.phi0).rem_euclid(TAU)
    }
    fn contains(&self, u: f64, phi: f64) -> bool {
        u >= self.u0 && u <= self.u1 && (self.full_ring() || self.rel_phi(phi) <= self.dphi)
    }
    fn centre(&self) -> (f64, f64) {
        if self.is_cap() {
            (1.0, 0.0)
        } else {
            (
                0.5 * (self.u0 + self.u1),
                (self.phi0 + 0.5 * self.dphi).rem_euclid(TAU),
            )
        }
    }
    fn theta_extent(&self) -> (f64, f64) {
        (self.u1.min(1.0).acos(), self.u0.max(0.0).acos())
    }
    /// Δθ and sin θ̄ Δφ (angular height and width).
    fn shape(&self) -> (f64, f64) {
        let (t0, t1) = self.theta_extent();
        let w = (0.5 * (t0 + t1)).sin().max(1e-12) * self.dphi;
        (t1 - t0, w)
    }
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum LeafKind {
    Regular,
    Oversampled,
    Exact(u32),
}

#[derive(Debug, Clone, PartialEq)]
struct Leaf {
    rect: Rect,
    kind: LeafKind,
    /// Exact representative (global vector) when set.
    rep: Option<DVec3>,
    id: usize,
}

#[derive(Debug, Clone, PartialEq)]
struct Ring {
    u0: f64,
    u1: f64,
    phi0: f64,
    cells: Vec<Node>,
}

#[derive(Debug, Clone, PartialEq)]
enum Node {
    Leaf(Leaf),
    /// Rings sorted from the highest u (pole side) down; each ring splits `extent.dphi` equally.
    Zonal {
        extent: Rect,
        rings: Vec<Ring>,
    },
    List {
        extent: Rect,
        children: Vec<Node>,
    },
}

impl Node {
    fn extent(&self) -> Rect {
        match self {
            Node::Leaf(l) => l.rect,
            Node::Zonal { extent, .. } | Node::List { extent, .. } => *extent,
        }
    }

    /// The leaf id of a zonal node's polar cap when `u` lies in it: the first ring (highest u)
    /// has one cell, a leaf, and `u ≥ u0` of that ring ([`zonal_cell`] then returns (0, 0)
    /// whatever φ). `None` otherwise (use [`Node::lookup`]).
    #[inline]
    fn cap_leaf(&self, u: f64) -> Option<usize> {
        if let Node::Zonal { rings, .. } = self
            && let Some(r) = rings.first()
            && r.u0 <= u
            && let [Node::Leaf(l)] = r.cells.as_slice()
        {
            return Some(l.id);
        }
        None
    }

    fn lookup(&self, u: f64, phi: f64) -> usize {
        match self {
            Node::Leaf(l) => l.id,
            Node::Zonal { extent, rings } => {
                let (k, j) = zonal_cell(extent, rings, u, phi);
                rings[k].cells[j].lookup(u, phi)
            }
            Node::List { children, .. } => children[pick_child(children, u, phi)].lookup(u, phi),
        }
    }

    fn for_each_leaf_mut(&mut self, f: &mut dyn FnMut(&mut Node)) {
        if matches!(self, Node::Leaf(_)) {
            f(self);
            return;
        }
        match self {
            Node::Zonal { rings, .. } => {
                for r in rings {
                    for c in &mut r.cells {
                        c.for_each_leaf_mut(f);
                    }
                }
            }
            Node::List { children, .. } => {
                for c in children {
                    c.for_each_leaf_mut(f);
                }
            }
            Node::Leaf(_) => {}
        }
    }

    fn leaf_mut(&mut self, u: f64, phi: f64) -> &mut Node {
        // Same descent as `lookup`, returning the leaf node.
        let idx: Option<(usize, usize)> = match self {
            Node::Leaf(_) => None,
            Node::Zonal { extent, rings } => Some(zonal_cell(extent, rings, u, phi)),
            Node::List { children, .. } => Some((usize::MAX, pick_child(children, u, phi))),
        };
        match (self, idx) {
            (n @ Node::Leaf(_), _) => n,
            (Node::Zonal { rings, .. }, Some((k, j))) => rings[k].cells[j].leaf_mut(u, phi),
            (Node::List { children, .. }, Some((_, i))) => children[i].leaf_mut(u, phi),
            (n, None) => n,
        }
    }
}

/// (ring, cell) of a zonal node containing (u, φ): ring by binary search on u, cell by the
/// azimuth offset from the ring's start (points outside a partial ring's azimuth range go to
/// the nearer end cell).
fn zonal_cell(extent: &Rect, rings: &[Ring], u: f64, phi: f64) -> (usize, usize) {
    let k = rings.partition_point(|r| r.u0 > u).min(rings.len() - 1);
    let r = &rings[k];
    let m = r.cells.len();
    let w = extent.dphi / m as f64;
    // (rem_euclid is a libm fmod call; inside [0, 2π) it returns its argument.)
    let mut rel = phi - r.phi0;
    if !(0.0..TAU).contains(&rel) {
        rel = rel.rem_euclid(TAU);
    }
    if !extent.full_ring() && rel > extent.dphi {
        rel = if rel > extent.dphi + 0.5 * (TAU - extent.dphi) {
            0.0
        } else {
            extent.dphi
        };
    }
    (k, ((rel / w) as usize).min(m - 1))
}

/// The child of a split node containing (u, φ); ties at shared boundaries go to the first
/// child, points lost to rounding to the nearest child.
fn pick_child(children: &[Node], u: f64, phi: f64) -> usize {
    if let Some(i) = children.iter().position(|c| c.extent().contains(u, phi)) {
        return i;
    }
    let mut best = (f64::INFINITY, 0usize);
    for (i, c) in children.iter().enumerate() {
        let e = c.extent();
        let du = if u < e.u0 {
            e.u0 - u
        } else if u > e.u1 {
            u - e.u1
        } else {
            0.0
        };
        let rel = e.rel_phi(phi);
        let dp = if e.full_ring() || rel <= e.dphi {
            0.0
        } else {
            (rel - e.dphi).min(TAU - rel)
        };
        if du + dp < best.0 {
            best = (du + dp, i);
        }
    }
    best.1
}

fn leaf(rect: Rect, kind: LeafKind) -> Node {
    Node::Leaf(Leaf {
        rect,
        kind,
        rep: None,
        id: 0,
    })
}

/// Zonal tiling of the cap `u ∈ [u_lo, 1]` × 2π into `n` cells of equal measure (equal solid
/// angle, or equal projected solid angle when `cos_weighted`) — physics.md §2.2 steps 1–5.
fn zonal_tiling(
    u_lo: f64,
    n: usize,
    layers: Option<usize>,
    cos_weighted: bool,
    kind: LeafKind,
) -> Node {
    let extent = Rect {
        u0: u_lo,
        u1: 1.0,
        phi0: 0.0,
        dphi: TAU,
    };
    let n = n.max(1);
    if n == 1 {
        return leaf(extent, kind);
    }
    // Measure coordinate s(u) ∈ [0, S]: 1 − u (solid angle) or 1 − u² (projected).
    let s_of = |u: f64| if cos_weighted { 1.0 - u * u } else { 1.0 - u };
    let u_of = |s: f64| {
        if cos_weighted {
            (1.0 - s).max(0.0).sqrt()
        } else {
            1.0 - s
        }
    };
    let s_tot = s_of(u_lo);
    if n < 5 {
        // Too few cells for a cap and a ring of ≥ 3: n wedges from the pole.
        let ring = Ring {
            u0: u_lo,
            u1: 1.0,
            phi0: 0.0,
            cells: (0..n)
                .map(|j| {
                    leaf(
                        Rect {
                            u0: u_lo,
                            u1: 1.0,
                            phi0: j as f64 * TAU / n as f64,
                            dphi: TAU / n as f64,
                        },
                        kind,
                    )
                })
                .collect(),
        };
        return Node::Zonal {
            extent,
            rings: vec![ring],
        };
    }
    let cell = s_tot / n as f64;
    let u_cap = u_of(cell);
    let theta_c = u_cap.acos();
    let theta_end = u_lo.acos();
    let d_omega = TAU * (1.0 - u_lo) / n as f64;
    let mut k_rings = match layers {
        Some(k) => k.clamp(1, n - 1),
        None => (((theta_end - theta_c) / d_omega.sqrt()).round() as usize).max(1),
    };
    let counts = loop {
        let mut counts = Vec::with_capacity(k_rings);
        let mut carry = 0.0;
        let mut used = 0usize;
        for k in 1..=k_rings {
            let ta = theta_c + (k - 1) as f64 * (theta_end - theta_c) / k_rings as f64;
            let tb = theta_c + k as f64 * (theta_end - theta_c) / k_rings as f64;
            let ideal = (s_of(tb.cos()) - s_of(ta.cos())) / cell;
            let m = if k == k_rings {
                n as i64 - 1 - used as i64
            } else {
                ((ideal + carry).round() as i64).max(1)
            };
            carry += ideal - m as f64;
            counts.push(m);
            used += m.max(0) as usize;
        }
        let min_m = if layers.is_some() { 1 } else { 3 };
        if counts.iter().all(|&m| m >= min_m) || k_rings == 1 {
            break counts;
        }
        k_rings -= 1;
    };
    let mut rings = Vec::with_capacity(k_rings + 1);
    rings.push(Ring {
        u0: u_cap,
        u1: 1.0,
        phi0: 0.0,
        cells: vec![leaf(
            Rect {
                u0: u_cap,
                u1: 1.0,
                phi0: 0.0,
                dphi: TAU,
            },
            kind,
        )],
    });
    let mut cum = 1usize;
    let mut u_hi = u_cap;
    for (k, &m) in counts.iter().enumerate() {
        let m = m.max(1) as usize;
        cum += m;
        let u_low = if k + 1 == counts.len() {
            u_lo
        } else {
            u_of(cum as f64 * cell)
        };
        let w = TAU / m as f64;
        let phi0 = if k % 2 == 0 { 0.0 } else { 0.5 * w };
        let cells = (0..m)
            .map(|j| {
                leaf(
                    Rect {
                        u0: u_low,
                        u1: u_hi,
                        phi0: (phi0 + j as f64 * w).rem_euclid(TAU),
                        dphi: w,
                    },
                    kind,
                )
            })
            .collect();
        rings.push(Ring {
            u0: u_low,
            u1: u_hi,
            phi0,
            cells,
        });
        u_hi = u_low;
    }
    Node::Zonal { extent, rings }
}

/// Splits a rectangle into a p × q grid of equal-solid-angle, near-square cells, about
/// `area/target` of them (at least `q_min` columns; caps use a zonal sub-tiling).
fn grid_split(rect: Rect, target: f64, kind: LeafKind) -> Node {
    let c = ((rect.area() / target).round() as usize).max(1);
    if rect.is_cap() {
        let mut z = zonal_tiling(rect.u0, c, None, false, kind);
        if let Node::Zonal { extent, .. } | Node::List { extent, .. } = &mut z {
            *extent = rect;
        }
        return z;
    }
    let (h, w) = rect.shape();
    let q_min = if rect.dphi > FRAC_PI_2 + 1e-12 {
        (rect.dphi / FRAC_PI_2).ceil() as usize
    } else {
        1
    };
    let mut p = (((c as f64) * h / w).sqrt().round() as usize).max(1);
    let mut q = ((c as f64 / p as f64).round() as usize).max(1);
    if q < q_min {
        q = q_min;
        p = ((c as f64 / q as f64).round() as usize).max(1);
    }
    if p == 1 && q == 1 {
        return leaf(rect, kind);
    }
    let du = (rect.u1 - rect.u0) / p as f64;
    let wq = rect.dphi / q as f64;
    let rings = (0..p)
        .map(|r| {
            let u1 = if r == 0 {
                rect.u1
            } else {
                rect.u1 - r as f64 * du
            };
            let u0 = if r + 1 == p {
                rect.u0
            } else {
                rect.u1 - (r + 1) as f64 * du
            };
            let cells = (0..q)
                .map(|j| {
                    let a = rect.phi0 + j as f64 * wq;
                    let d = if j + 1 == q {
                        rect.phi0 + rect.dphi - a
                    } else {
                        wq
                    };
                    leaf(
                        Rect {
                            u0,
                            u1,
                            phi0: a.rem_euclid(TAU),
                            dphi: d,
                        },
                        kind,
                    )
                })
                .collect();
            Ring {
                u0,
                u1,
                phi0: rect.phi0,
                cells,
            }
        })
        .collect();
    Node::Zonal {
        extent: rect,
        rings,
    }
}

/// Hemisphere-local (u, φ) of a global vector and its hemisphere (0 upper, 1 lower).
fn local(v: DVec3) -> (usize, f64, f64) {
    let len = v.length();
    if !(len.is_finite() && len > 0.0) {
        return (0, 1.0, 0.0);
    }
    let z = v.z / len;
    let hemi = if z >= 0.0 { 0 } else { 1 };
    (hemi, z.abs().min(1.0), azimuth(v))
}

fn global(hemi: usize, u: f64, phi: f64) -> DVec3 {
    let st = (1.0 - u * u).max(0.0).sqrt();
    let (sp, cp) = phi.sin_cos();
    DVec3::new(st * cp, st * sp, if hemi == 0 { u } else { -u })
}

/// Splits leaf `l` so that `target` (global, hemisphere-local `(ut, pt)`) becomes an exact
/// direction of about `omega` sr (physics.md §2.3).
fn split_for_exact(l: &Leaf, ut: f64, pt: f64, target: DVec3, omega: f64, tag: u32) -> Node {
    let r = l.rect;
    if r.area() <= 1.5 * omega {
        return exact_leaf(r, target, tag);
    }
    let rem_kind = l.kind;
    let target_size = r.area();
    let st = (1.0 - ut * ut).max(0.0).sqrt();
    if st < 1e-9 && r.is_cap() {
        return split_cap_for_exact(r, target, omega, tag, rem_kind);
    }
    let (du_h, dphi_h) = exact_half_widths(r, st, omega);
    let (lo, hi) = exact_u_range(r, ut, du_h);
    let (a, b) = exact_phi_range(r, pt, dphi_h);
    let mut children = vec![exact_leaf(
        Rect {
            u0: lo,
            u1: hi,
            phi0: a.rem_euclid(TAU),
            dphi: b - a,
        },
        target,
        tag,
    )];
    for rem in exact_remainders(r, (lo, hi), (a, b)) {
        if rem.area() <= 0.0 {
            continue;
        }
        children.push(grid_split(rem, target_size, rem_kind));
    }
    Node::List {
        extent: r,
        children,
    }
}

/// Step of [`split_for_exact`]: the exact leaf of `rect`, represented by `target`.
fn exact_leaf(rect: Rect, target: DVec3, tag: u32) -> Node {
    Node::Leaf(Leaf {
        rect,
        kind: LeafKind::Exact(tag),
        rep: Some(target),
        id: 0,
    })
}

/// Step of [`split_for_exact`] for an exact zenith/nadir in the cap `r`: a small exact cap of
/// `omega` sr plus an annulus cut into near-square wedges of kind `rem_kind`.
fn split_cap_for_exact(r: Rect, target: DVec3, omega: f64, tag: u32, rem_kind: LeafKind) -> Node {
    let mut children = Vec::new();
    let u_s = 1.0 - omega / TAU;
    children.push(exact_leaf(
        Rect {
            u0: u_s,
            u1: 1.0,
            phi0: 0.0,
            dphi: TAU,
        },
        target,
        tag,
    ));
    let ann = Rect {
        u0: r.u0,
        u1: u_s,
        phi0: 0.0,
        dphi: TAU,
    };
    let (h, w) = ann.shape();
    let q = ((w / h).round() as usize).max(3);
    let wq = TAU / q as f64;
    for j in 0..q {
        children.push(leaf(
            Rect {
                u0: r.u0,
                u1: u_s,
                phi0: j as f64 * wq,
                dphi: wq,
            },
            rem_kind,
        ));
    }
    Node::List {
        extent: r,
        children,
    }
}

/// Step of [`split_for_exact`]: the half widths `(du, dφ)` of a near-square exact cell of
/// `omega` sr at sin θ = `st` inside `r` (dφ capped at π/4 and half the parent's azimuth
/// span; du capped at half the parent's μ span).
fn exact_half_widths(r: Rect, st: f64, omega: f64) -> (f64, f64) {
    let half = omega.sqrt() / 2.0;
    let cap_phi = if r.full_ring() {
        FRAC_PI_4
    } else {
        (0.5 * r.dphi).min(FRAC_PI_4)
    };
    let mut dphi_h = (half / st.max(1e-12)).min(cap_phi);
    let mut du_h = omega / (4.0 * dphi_h);
    if 2.0 * du_h > r.u1 - r.u0 {
        du_h = 0.5 * (r.u1 - r.u0);
        dphi_h = (omega / (4.0 * du_h)).min(cap_phi);
    }
    (du_h, dphi_h)
}

/// Step of [`split_for_exact`]: the exact cell's μ range around `ut`, shifted inside the
/// parent `r`, then thin remainders snapped away.
fn exact_u_range(r: Rect, ut: f64, du_h: f64) -> (f64, f64) {
    let (mut lo, mut hi) = (ut - du_h, ut + du_h);
    if lo < r.u0 {
        hi += r.u0 - lo;
        lo = r.u0;
    }
    if hi > r.u1 {
        lo -= hi - r.u1;
        hi = r.u1;
    }
    lo = lo.max(r.u0);
    if lo - r.u0 < 0.25 * (hi - lo) {
        lo = r.u0;
    }
    if r.u1 - hi < 0.25 * (hi - lo) {
        hi = r.u1;
    }
    (lo, hi)
}

/// Step of [`split_for_exact`]: the exact cell's azimuth range `(a, b)` around `pt` (a full
/// ring: centred on `pt`; a sector: shifted inside it, thin remainders snapped away).
fn exact_phi_range(r: Rect, pt: f64, dphi_h: f64) -> (f64, f64) {
    if r.full_ring() {
        let a = (pt - dphi_h).rem_euclid(TAU);
        (a, a + 2.0 * dphi_h)
    } else {
        let rel = r.rel_phi(pt).min(r.dphi);
        let (mut a, mut b) = (rel - dphi_h, rel + dphi_h);
        if a < 0.0 {
            b -= a;
            a = 0.0;
        }
        if b > r.dphi {
            a -= b - r.dphi;
            b = r.dphi;
        }
        a = a.max(0.0);
        if a < 0.25 * (b - a) {
            a = 0.0;
        }
        if r.dphi - b < 0.25 * (b - a) {
            b = r.dphi;
        }
        (r.phi0 + a, r.phi0 + b)
    }
}

/// Step of [`split_for_exact`]: the parts of `r` around the exact cell `[lo, hi] × [a, b]`
/// (above, below, then beside it in azimuth), possibly empty.
fn exact_remainders(r: Rect, (lo, hi): (f64, f64), (a, b): (f64, f64)) -> Vec<Rect> {
    let mut rems = Vec::new();
    if hi < r.u1 {
        rems.push(Rect {
            u0: hi,
            u1: r.u1,
            phi0: r.phi0,
            dphi: r.dphi,
        });
    }
    if lo > r.u0 {
        rems.push(Rect {
            u0: r.u0,
            u1: lo,
            phi0: r.phi0,
            dphi: r.dphi,
        });
    }
    if r.full_ring() {
        rems.push(Rect {
            u0: lo,
            u1: hi,
            phi0: b.rem_euclid(TAU),
            dphi: TAU - (b - a),
        });
    } else {
        if a > r.phi0 {
            rems.push(Rect {
                u0: lo,
                u1: hi,
                phi0: r.phi0,
                dphi: a - r.phi0,
            });
        }
        if b < r.phi0 + r.dphi {
            rems.push(Rect {
                u0: lo,
                u1: hi,
                phi0: b.rem_euclid(TAU),
                dphi: r.phi0 + r.dphi - b,
            });
        }
    }
    rems
}

/// Splits an exact leaf holding representative `a` so that a second exact direction `b` gets
/// its own half (cut midway between them along the more separated axis).
fn split_two_exact(
    l: &Leaf,
    hemi_u_a: (f64, f64),
    b: (f64, f64),
    target_b: DVec3,
    tag_b: u32,
) -> Node {
    let r = l.rect;
    let (ua, pa) = hemi_u_a;
    let (ub, pb) = b;
    let st = (1.0 - (0.5 * (ua + ub)).powi(2)).max(0.0).sqrt();
    let dtheta = (ua.clamp(-1.0, 1.0).acos() - ub.clamp(-1.0, 1.0).acos()).abs();
    let ra = r.rel_phi(pa);
    let rb = r.rel_phi(pb);
    let dphi = (ra - rb).abs().min(TAU - (ra - rb).abs()) * st;
    let mk = |rect: Rect, rep: Option<DVec3>, tag: u32| {
        Node::Leaf(Leaf {
            rect,
            kind: LeafKind::Exact(tag),
            rep,
            id: 0,
        })
    };
    let tag_a = match l.kind {
        LeafKind::Exact(t) => t,
        _ => 0,
    };
    let (ra_rect, rb_rect) = if dtheta >= dphi || r.full_ring() {
        let cut = 0.5 * (ua + ub);
        let low = Rect {
            u0: r.u0,
            u1: cut,
            ..r
        };
        let high = Rect {
            u0: cut,
            u1: r.u1,
            ..r
        };
        if ua > ub { (high, low) } else { (low, high) }
    } else {
        let cut = 0.5 * (ra + rb);
        let first = Rect { dphi: cut, ..r };
        let second = Rect {
            phi0: (r.phi0 + cut).rem_euclid(TAU),
            dphi: r.dphi - cut,
            ..r
        };
        if ra < rb {
            (first, second)
        } else {
            (second, first)
        }
    };
    Node::List {
        extent: r,
        children: vec![
            mk(ra_rect, l.rep, tag_a),
            mk(rb_rect, Some(target_b), tag_b),
        ],
    }
}

// ---------------------------------------------------------------------------------------------
// The public set
// ---------------------------------------------------------------------------------------------

/// The discrete directions of a scene: regular/oversampled/exact directions tiling 4π (indices
/// `0..n_regular()`, upper hemisphere first, pole to horizon) then fictive directions.
#[derive(Debug, Clone, Serialize)]
pub struct DirectionSet {
    /// All directions (tiling first, fictive last).
    pub directions: Vec<Direction>,
    n_regular: usize,
    n_sectors: usize,
    exact_index: Vec<usize>,
    params: DirectionParams,
    #[serde(skip)]
    roots: Vec<Node>,
}

impl DirectionSet {
    /// Builds the set (validation errors name the offending field).
    pub fn new(params: &DirectionParams) -> Result<Self, DirectionError> {
        validate(params)?;
        let n_h = params.count.div_ceil(2);
        let mut roots: Vec<Node> = (0..2)
            .map(|_| {
                zonal_tiling(
                    0.0,
                    n_h,
                    params.layers,
                    params.cos_weighted,
                    LeafKind::Regular,
                )
            })
            .collect();

        // Oversampled regions.
        for region in &params.oversample {
            let w = region.solid_angle();
            let centre = region.centre();
            let (ch, cu, cp) = local(centre);
            for (hemi, root) in roots.iter_mut().enumerate() {
                root.for_each_leaf_mut(&mut |node| {
                    let Node::Leaf(l) = node else { return };
                    let (u, p) = l.rect.centre();
                    let inside = region.contains(global(hemi, u, p))
                        || (hemi == ch && l.rect.contains(cu, cp));
                    if inside && l.rect.area() > 1.5 * w {
                        *node = grid_split(l.rect, w, LeafKind::Oversampled);
                    }
                });
            }
        }

        // Exact directions.
        let mut alias: Vec<(usize, u32)> = Vec::new();
        for (k, e) in params.exact.iter().enumerate() {
            let target = e.omega();
            let (hemi, ut, pt) = local(target);
            let w = e.solid_angle_sr.unwrap_or(params.exact_solid_angle_sr);
            let node = roots[hemi].leaf_mut(ut, pt);
            let Node::Leaf(l) = node else {
                unreachable!("leaf_mut returns a leaf")
            };
            match (l.kind, l.rep) {
                (LeafKind::Exact(t), Some(rep)) => {
                    if rep.angle_between(target) < 1e-9 {
                        alias.push((k, t));
                    } else {
                        let (_, ua, pa) = local(rep);
                        *node = split_two_exact(l, (ua, pa), (ut, pt), target, k as u32);
                    }
                }
                _ => *node = split_for_exact(l, ut, pt, target, w, k as u32),
            }
        }

        // Number the leaves and emit directions.
        let mut directions = Vec::new();
        for (hemi, root) in roots.iter_mut().enumerate() {
            root.for_each_leaf_mut(&mut |node| {
                let Node::Leaf(l) = node else { return };
                l.id = directions.len();
                directions.push(emit(hemi, l));
            });
        }
        let n_regular = directions.len();
        let mut exact_index = vec![usize::MAX; params.exact.len()];
        for (i, d) in directions.iter().enumerate() {
            if let DirectionKind::Exact { tag } = d.kind {
                exact_index[tag as usize] = i;
            }
        }
        for (k, t) in alias {
            exact_index[k] = exact_index[t as usize];
        }

        // Angular sectors.
        let n_sectors = assign_sectors(&mut directions, params.sectors);

        // Fictive directions (appended, sector of their containing tiling direction).
        let mut set = Self {
            directions,
            n_regular,
            n_sectors,
            exact_index,
            params: params.clone(),
            roots,
        };
        for (k, f) in params.fictive.iter().enumerate() {
            let v = f.omega();
            let w = f.solid_angle_sr.unwrap_or(params.exact_solid_angle_sr);
            let host = set.find_sector(v);
            let (mu, phi) = (v.z, azimuth(v));
            let half_mu = (0.25 * w).sqrt().min(1.0);
            let dphi = w / (2.0 * half_mu);
            set.directions.push(Direction {
                omega: v,
                mu_min: (mu - half_mu).max(-1.0),
                mu_max: (mu + half_mu).min(1.0),
                phi_min: (phi - 0.5 * dphi).rem_euclid(TAU),
                phi_max: (phi - 0.5 * dphi).rem_euclid(TAU) + dphi,
                solid_angle_sr: w,
                projected_sr: mu.abs() * w,
                kind: DirectionKind::Fictive { tag: k as u32 },
                sector: set.directions[host].sector,
            });
        }
        Ok(set)
    }

    /// DART defaults with `count` directions.
    pub fn with_count(count: usize) -> Result<Self, DirectionError> {
        Self::new(&DirectionParams::with_count(count))
    }

    /// The parameters the set was built from.
    pub fn params(&self) -> &DirectionParams {
        &self.params
    }

    /// Number of all directions (tiling + fictive).
    pub fn len(&self) -> usize {
        self.directions.len()
    }

    /// True when empty (never, for a valid set).
    pub fn is_empty(&self) -> bool {
        self.directions.is_empty()
    }

    /// Number of directions tiling 4π (indices `0..n_regular`).
    pub fn n_regular(&self) -> usize {
        self.n_regular
    }

    /// The directions tiling 4π.
    pub fn tiling(&self) -> &[Direction] {
        &self.directions[..self.n_regular]
    }

    /// The fictive directions (indices `n_regular..len`).
    pub fn fictive(&self) -> &[Direction] {
        &self.directions[self.n_regular..]
    }

    /// Number of (non-empty) angular sectors; `Direction::sector < n_sectors`.
    pub fn n_sectors(&self) -> usize {
        self.n_sectors
    }

    /// Index of the direction made exact for request `k` of `DirectionParams::exact`.
    pub fn exact_index(&self, k: usize) -> Option<usize> {
        self.exact_index
            .get(k)
            .copied()
            .filter(|&i| i != usize::MAX)
    }

    /// Index of the tiling direction whose sector contains `omega` (a propagation vector, need
    /// not be normalised) — the flexible-direction hook (seed eq. 4): O(log N) (binary search of
    /// the ring by μ, then azimuth arithmetic, then at most a few split children).
    /// μ = 0 goes to the upper hemisphere; zero or non-finite vectors map to the +z cap.
    pub fn find_sector(&self, omega: DVec3) -> usize {
        // Fast path (same result as the full lookup): a direction inside the polar cap of its
        // hemisphere (the first ring holds one leaf, so neither the azimuth nor the ring search
        // matters), e.g. every return toward a nadir LiDAR receiver.
        let len = omega.length();
        if len.is_finite() && len > 0.0 {
            let z = omega.z / len;
            let h = if z >= 0.0 { 0 } else { 1 };
            if let Some(id) = self.roots[h].cap_leaf(z.abs().min(1.0)) {
                return id;
            }
        }
        let (h, u, p) = local(omega);
        self.roots[h].lookup(u, p)
    }

    /// Σ ΔΩ over the tiling (4π).
    pub fn total_solid_angle(&self) -> f64 {
        self.tiling().iter().map(|d| d.solid_angle_sr).sum()
    }

    /// `[(ΣΔΩ, Σ μ̄ΔΩ) upper, (ΣΔΩ, Σ |μ̄|ΔΩ) lower]` over the tiling (2π and π each).
    pub fn hemisphere_sums(&self) -> [(f64, f64); 2] {
        let mut s = [(0.0, 0.0); 2];
        for d in self.tiling() {
            let h = if d.is_upward() { 0 } else { 1 };
            s[h].0 += d.solid_angle_sr;
            s[h].1 += d.projected_sr;
        }
        s
    }

    /// (min, max) aspect ratio `Δθ/(sin θ̄ Δφ)` over regular (non-split, non-cap) sectors.
    pub fn aspect_ratio_range(&self) -> (f64, f64) {
        self.aspect_range(|d| d.kind == DirectionKind::Regular)
    }

    /// (min, max) aspect ratio over every non-cap tiling sector (remainders included).
    pub fn aspect_ratio_range_all(&self) -> (f64, f64) {
        self.aspect_range(|_| true)
    }

    fn aspect_range(&self, keep: impl Fn(&Direction) -> bool) -> (f64, f64) {
        self.tiling()
            .iter()
            .filter(|d| keep(d))
            .filter_map(|d| d.aspect_ratio())
            .fold((f64::INFINITY, 0.0f64), |(a, b), r| (a.min(r), b.max(r)))
    }

    /// Indices of the tiling directions in angular sector `k`.
    pub fn sector_members(&self, k: u16) -> Vec<usize> {
        (0..self.n_regular)
            .filter(|&i| self.directions[i].sector == k)
            .collect()
    }
}

fn emit(hemi: usize, l: &Leaf) -> Direction {
    let r = l.rect;
    let (mu_min, mu_max) = if hemi == 0 {
        (r.u0, r.u1)
    } else {
        (-r.u1, -r.u0)
    };
    let omega = match l.rep {
        Some(v) => v,
        None => {
            let (u, p) = r.centre();
            global(hemi, u, p)
        }
    };
    let kind = match l.kind {
        LeafKind::Regular => DirectionKind::Regular,
        LeafKind::Oversampled => DirectionKind::Oversampled,
        LeafKind::Exact(tag) => DirectionKind::Exact { tag },
    };
    let phi_min = r.phi0.rem_euclid(TAU);
    Direction {
        omega,
        mu_min,
        mu_max,
        phi_min,
        phi_max: phi_min + r.dphi,
        solid_angle_sr: r.dphi * (r.u1 - r.u0),
        projected_sr: 0.5 * r.dphi * (r.u1 * r.u1 - r.u0 * r.u0),
        kind,
        sector: 0,
    }
}

/// Groups neighbouring directions into `k` angular sectors (physics.md §6.3 [rec]): a coarse
/// zonal tiling with ⌈k/2⌉ cells in the upper and ⌊k/2⌋ in the lower hemisphere; each direction
/// joins the coarse cell containing its representative; empty cells are dropped. Returns the
/// number of sectors. `k ≥ n` gives one sector per direction.
fn assign_sectors(dirs: &mut [Direction], k: usize) -> usize {
    let n = dirs.len();
    if k >= n {
        for (i, d) in dirs.iter_mut().enumerate() {
            d.sector = i as u16;
        }
        return n;
    }
    if k <= 1 {
        dirs.iter_mut().for_each(|d| d.sector = 0);
        return 1;
    }
    let ku = k.div_ceil(2);
    let kl = (k / 2).max(1);
    let mut coarse = [
        zonal_tiling(0.0, ku, None, false, LeafKind::Regular),
        zonal_tiling(0.0, kl, None, false, LeafKind::Regular),
    ];
    for c in &mut coarse {
        let mut id = 0;
        c.for_each_leaf_mut(&mut |node| {
            if let Node::Leaf(l) = node {
                l.id = id;
                id += 1;
            }
        });
    }
    let raw: Vec<usize> = dirs
        .iter()
        .map(|d| {
            // The sector's own hemisphere decides (a horizon representative may sit at μ = 0).
            let (_, u, p) = local(d.omega);
            let hh = if d.is_upward() { 0 } else { 1 };
            (if hh == 0 { 0 } else { ku }) + coarse[hh].lookup(u, p)
        })
        .collect();
    let mut map = vec![usize::MAX; ku + kl];
    let mut used: Vec<usize> = raw.clone();
    used.sort_unstable();
    used.dedup();
    for (new, &old) in used.iter().enumerate() {
        map[old] = new;
    }
    for (d, r) in dirs.iter_mut().zip(raw) {
        d.sector = map[r] as u16;
    }
    used.len()
}
