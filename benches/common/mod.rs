//! Shared helpers of the benches.

/// Peak resident set size of this process, MiB (VmHWM from /proc/self/status; NaN elsewhere).
#[allow(dead_code)]
pub fn peak_rss_mib() -> f64 {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("VmHWM:"))
                .and_then(|l| l.split_whitespace().nth(1)?.parse::<f64>().ok())
        })
        .map_or(f64::NAN, |kib| kib / 1024.0)
}

/// Sets the leaf size of every turbid material to 0 (no hotspot), so that the scene is the pure
/// turbid medium the DISORT oracle solves.
#[allow(dead_code)]
pub fn no_hotspot(d: &mut lumenscape::scene::desc::SceneDesc) {
    for o in d.optics.values_mut() {
        if let lumenscape::scene::desc::OpticsDesc::Turbid { leaf_size_m, .. } = o {
            *leaf_size_m = 0.0;
        }
    }
}
