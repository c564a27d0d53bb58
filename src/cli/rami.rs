//! `lumenscape rami-mes --run DIR --case EXP --model NAME [--out DIR/rami]`: converts a finished
//! run (its `summary.json`) into the RAMI measurement files (`brfpp`, `brfop` and their
//! `_co_sgl`/`_uc_sgl`/`_mlt` parts when the solver separates them, `brf1`, `fabs`, `ftran`),
//! named `<MES>_<MODEL>-<EXP>.mes` as the ROMC wants, plus `measurements.json` holding the same
//! values (see [`crate::io::rami_mes`]). The run's `summary.json` already holds every value the
//! files are made of (each BRF entry with its standard error and RAMI parts, albedo, fabs,
//! ftran); this command selects the RAMI views and re-formats them.

use crate::io::atomic::write_atomic;
use crate::io::rami_mes::{RunSummary, measurements_from_run};
use crate::scene::generators::rami::RamiCase;
use std::io::Write;
use std::path::PathBuf;

/// `rami-mes` arguments.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Output folder of a finished `lumenscape run` (holding summary.json).
    #[arg(long)]
    pub run: PathBuf,
    /// RAMI experiment identifier, e.g. HOM13_DIS_PLA_NIR_20.
    #[arg(long)]
    pub case: String,
    /// Model name registered with the ROMC (1–10 letters or digits).
    #[arg(long)]
    pub model: String,
    /// Band of the run to convert (default: the only band, or the one named after the case's
    /// band tag, e.g. `nir`).
    #[arg(long)]
    pub band: Option<String>,
    /// Folder for the .mes files (default RUN/rami; created if needed).
    #[arg(long)]
    pub out: Option<PathBuf>,
}

/// Runs `rami-mes`.
pub fn run(args: &Args, out: &mut dyn Write) -> Result<(), String> {
    let summary_path = args.run.join("summary.json");
    let text = std::fs::read_to_string(&summary_path).map_err(|e| {
        format!(
            "{}: {e} (is {} the --out folder of a finished `lumenscape run`?)",
            summary_path.display(),
            args.run.display()
        )
    })?;
    let summary: RunSummary = serde_json::from_str(&text)
        .map_err(|e| format!("{}: not a run summary: {e}", summary_path.display()))?;
    let experiment = args.case.trim().to_ascii_uppercase();
    match RamiCase::parse(&experiment) {
        Ok(case) => {
            let d = (case.sun_zenith_deg - summary.settings.sun_zenith_deg).abs();
            if !(d <= 0.01) {
                return Err(format!(
                    "case {experiment} has a sun zenith of {}° but the run's is {}°: wrong --case or --run?",
                    case.sun_zenith_deg, summary.settings.sun_zenith_deg
                ));
            }
        }
        Err(e) => writeln!(
            out,
            "note: no consistency check of the run against the case ({e})"
        )
        .map_err(|e| e.to_string())?,
    }
    let m = measurements_from_run(&summary, args.band.as_deref(), &experiment, &args.model)?;
    let dir = args.out.clone().unwrap_or_else(|| args.run.join("rami"));
    std::fs::create_dir_all(&dir)
        .map_err(|e| format!("{}: cannot create folder: {e}", dir.display()))?;
    let files = m.mes_files();
    for (name, content) in &files {
        write_atomic(&dir.join(name), content.as_bytes())?;
    }
    let json = serde_json::to_string_pretty(&m).map_err(|e| e.to_string())?;
    write_atomic(&dir.join("measurements.json"), json.as_bytes())?;
    let w = |out: &mut dyn Write, s: String| writeln!(out, "{s}").map_err(|e| e.to_string());
    w(
        out,
        format!(
            "{} .mes files and measurements.json written to {} (band `{}`, {} solver):",
            files.len(),
            dir.display(),
            m.band,
            m.solver
        ),
    )?;
    for (name, _) in &files {
        w(out, format!("  {name}"))?;
    }
    if !m.has_components() {
        w(
            out,
            "the _co_sgl, _uc_sgl and _mlt parts need the Monte Carlo solver (--solver monte-carlo): not written"
                .into(),
        )?;
    }
    Ok(())
}
