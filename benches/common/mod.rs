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

/// CPU time of this process so far (user + system, all threads), seconds, from
/// /proc/self/stat (clock ticks of 1/100 s, Linux's `USER_HZ`); NaN elsewhere.
#[allow(dead_code)]
pub fn cpu_seconds() -> f64 {
    std::fs::read_to_string("/proc/self/stat")
        .ok()
        .and_then(|s| {
            // Fields after the command name (which may contain spaces) start at state (field 3).
            let rest = &s[s.rfind(')')? + 2..];
            let f: Vec<&str> = rest.split_whitespace().collect();
            let ticks = f.get(11)?.parse::<f64>().ok()? + f.get(12)?.parse::<f64>().ok()?;
            Some(ticks / 100.0)
        })
        .unwrap_or(f64::NAN)
}
