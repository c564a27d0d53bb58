//! `lumenscape prospect`: PROSPECT-5/D leaf reflectance and transmittance as CSV
//! (`wavelength_nm,reflectance,transmittance`, 400–2500 nm at 1 nm).
//!
//! Reads the leaf parameters from the command line (and optionally a spectral data table in the
//! format of `assets/optics/prospect_spectra.csv`; the compiled-in table by default), writes CSV.

use std::path::PathBuf;

use crate::physics::prospect::{
    PROSPECT_DEFAULT_ALPHA_DEG, ProspectData, ProspectModel, ProspectParams, prospect_with_alpha,
};

/// Arguments of `lumenscape prospect`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// PROSPECT version: `5` (PROSPECT-5, Féret et al. 2008) or `D` (PROSPECT-D, Féret et al. 2017).
    #[arg(long)]
    pub model: ProspectModel,
    /// Leaf structure parameter N (≥ 1).
    #[arg(long)]
    pub n: f64,
    /// Chlorophyll a+b content, µg cm⁻².
    #[arg(long)]
    pub cab: f64,
    /// Carotenoid content, µg cm⁻².
    #[arg(long)]
    pub car: f64,
    /// Anthocyanin content, µg cm⁻² (PROSPECT-D only; must be 0 with `--model 5`).
    #[arg(long, default_value_t = 0.0)]
    pub anth: f64,
    /// Brown pigment content, arbitrary units (typically 0–1).
    #[arg(long, default_value_t = 0.0)]
    pub cbrown: f64,
    /// Equivalent water thickness, cm (g cm⁻²).
    #[arg(long)]
    pub cw: f64,
    /// Dry matter content, g cm⁻².
    #[arg(long)]
    pub cm: f64,
    /// Half-angle of the illumination cone on the top leaf surface, degrees (PROSPECT uses 40).
    #[arg(long, default_value_t = PROSPECT_DEFAULT_ALPHA_DEG)]
    pub alpha_deg: f64,
    /// Spectral data table to use instead of the compiled-in one (format of
    /// assets/optics/prospect_spectra.csv).
    #[arg(long)]
    pub data: Option<PathBuf>,
}

/// Runs the subcommand: writes `wavelength_nm,reflectance,transmittance` rows to `out`.
/// Errors are user-facing messages (bad parameter naming the option, unreadable data file, I/O).
pub fn run(args: &Args, out: &mut dyn std::io::Write) -> Result<(), String> {
    if args.model == ProspectModel::P5 && args.anth != 0.0 {
        return Err(format!(
            "--anth {} given with --model 5: PROSPECT-5 has no anthocyanin absorption; use --model D or omit --anth",
            args.anth
        ));
    }
    let params = ProspectParams {
        n: args.n,
        cab_ug_cm2: args.cab,
        car_ug_cm2: args.car,
        anth_ug_cm2: args.anth,
        cbrown: args.cbrown,
        cw_cm: args.cw,
        cm_g_cm2: args.cm,
    };
    let loaded;
    let data = match &args.data {
        Some(path) => {
            loaded = ProspectData::load(path).map_err(|e| e.to_string())?;
            &loaded
        }
        None => ProspectData::builtin(),
    };
    let leaf = prospect_with_alpha(args.model, &params, data, args.alpha_deg)
        .map_err(|e| option_names(&e.to_string()))?;
    let io = |e: std::io::Error| format!("cannot write output: {e}");
    writeln!(out, "wavelength_nm,reflectance,transmittance").map_err(io)?;
    for i in 0..leaf.wavelength_nm.len() {
        writeln!(
            out,
            "{},{:.10},{:.10}",
            leaf.wavelength_nm[i], leaf.reflectance[i], leaf.transmittance[i]
        )
        .map_err(io)?;
    }
    Ok(())
}

/// Rewrites library field names into the command-line option names in a message.
fn option_names(message: &str) -> String {
    let mut m = message.to_string();
    for (field, option) in [
        ("`n`", "`--n`"),
        ("`cab_ug_cm2`", "`--cab`"),
        ("`car_ug_cm2`", "`--car`"),
        ("`anth_ug_cm2`", "`--anth`"),
        ("`cbrown`", "`--cbrown`"),
        ("`cw_cm`", "`--cw`"),
        ("`cm_g_cm2`", "`--cm`"),
        ("`alpha_deg`", "`--alpha-deg`"),
    ] {
        m = m.replace(field, option);
    }
    m
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser;

    #[derive(clap::Parser)]
    struct Cli {
        #[command(flatten)]
        args: Args,
    }

    fn run_with(argv: &[&str]) -> Result<String, String> {
        let cli = Cli::try_parse_from(std::iter::once("prospect").chain(argv.iter().copied()))
            .map_err(|e| e.to_string())?;
        let mut out = Vec::new();
        run(&cli.args, &mut out)?;
        Ok(String::from_utf8(out).unwrap())
    }

    #[test]
    fn prints_2101_rows_of_csv() {
        let text = run_with(&[
            "--model", "D", "--n", "1.5", "--cab", "40", "--car", "8", "--anth", "1", "--cw",
            "0.01", "--cm", "0.009",
        ])
        .unwrap();
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(lines[0], "wavelength_nm,reflectance,transmittance");
        assert_eq!(lines.len(), 1 + 2101);
        assert!(lines[1].starts_with("400,"));
        assert!(lines[2101].starts_with("2500,"));
        for l in &lines[1..] {
            let v: Vec<f64> = l.split(',').map(|x| x.parse().unwrap()).collect();
            assert!(v[1] > 0.0 && v[1] < 1.0 && v[2] >= 0.0 && v[1] + v[2] <= 1.0);
        }
        let p5 = run_with(&[
            "--model", "5", "--n", "1.5", "--cab", "40", "--car", "8", "--cw", "0.01", "--cm",
            "0.009",
        ])
        .unwrap();
        assert_eq!(p5.lines().count(), 2102);
    }

    #[test]
    fn errors_name_the_option() {
        let e = run_with(&[
            "--model", "D", "--n", "0.5", "--cab", "40", "--car", "8", "--cw", "0.01", "--cm",
            "0.009",
        ])
        .unwrap_err();
        assert!(e.contains("`--n`"), "{e}");
        let e = run_with(&[
            "--model", "D", "--n", "1.5", "--cab=-3", "--car", "8", "--cw", "0.01", "--cm", "0.009",
        ])
        .unwrap_err();
        assert!(e.contains("`--cab`") && e.contains("non-negative"), "{e}");
        let e = run_with(&[
            "--model", "5", "--n", "1.5", "--cab", "40", "--car", "8", "--anth", "2", "--cw",
            "0.01", "--cm", "0.009",
        ])
        .unwrap_err();
        assert!(e.contains("--anth"), "{e}");
        let e = run_with(&[
            "--model", "4", "--n", "1.5", "--cab", "40", "--car", "8", "--cw", "0.01", "--cm",
            "0.009",
        ])
        .unwrap_err();
        assert!(e.contains("unknown PROSPECT model"), "{e}");
        let e = run_with(&[
            "--model",
            "D",
            "--n",
            "1.5",
            "--cab",
            "40",
            "--car",
            "8",
            "--cw",
            "0.01",
            "--cm",
            "0.009",
            "--data",
            "/no/such/table.csv",
        ])
        .unwrap_err();
        assert!(e.contains("/no/such/table.csv"), "{e}");
    }
}
