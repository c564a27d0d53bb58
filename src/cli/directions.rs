//! `lumenscape directions`: builds the discrete direction set of physics.md §2 and prints it so
//! users can inspect and plot it.
//!
//! Output columns: `index`, `zenith_deg`, `azimuth_deg`, `solid_angle_sr`, `kind`, `sector`.
//! Angles are those of the **propagation vector** Ω (z up, azimuth anticlockwise from +x, DART
//! convention, physics.md §1.1): upward directions (zenith < 90°) coincide with DART's
//! ground→sensor view angles; downward ones (zenith > 90°) are "sun to ground" propagation
//! angles (a sun at view angles (30°, 225°) propagates along (150°, 45°)). `--exact` takes the
//! same propagation angles.

use crate::direction::{DirectionParams, DirectionSet, ExactDirection, OversampleRegion};

/// Output format.
#[derive(clap::ValueEnum, Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Format {
    /// A JSON array of objects.
    #[default]
    Json,
    /// CSV with a header line.
    Csv,
}

/// Arguments of `lumenscape directions`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Number of regular directions over 4π (DART default 100).
    #[arg(long, default_value_t = 100)]
    pub count: usize,
    /// Oversampled cone: ZENITH_DEG,AZIMUTH_DEG,HALF_ANGLE_DEG,SOLID_ANGLE_SR (repeatable).
    #[arg(long = "oversample-cone", value_name = "ZEN,AZ,HALF_ANGLE,SOLID_ANGLE", value_parser = parse_cone, allow_hyphen_values = true)]
    pub oversample_cone: Vec<[f64; 4]>,
    /// Exact direction: ZENITH_DEG,AZIMUTH_DEG of the propagation vector (repeatable).
    #[arg(long, value_name = "ZEN,AZ", value_parser = parse_pair, allow_hyphen_values = true)]
    pub exact: Vec<[f64; 2]>,
    /// Fictive direction: ZENITH_DEG,AZIMUTH_DEG (repeatable).
    #[arg(long, value_name = "ZEN,AZ", value_parser = parse_pair, allow_hyphen_values = true)]
    pub fictive: Vec<[f64; 2]>,
    /// Solid angle of exact and fictive directions, sr.
    #[arg(long, default_value_t = 0.001)]
    pub exact_solid_angle: f64,
    /// Equal projected solid angle instead of equal solid angle.
    #[arg(long)]
    pub cos_weighted: bool,
    /// Zenith rings per hemisphere (default automatic).
    #[arg(long)]
    pub layers: Option<usize>,
    /// Number of angular sectors for interception storage.
    #[arg(long, default_value_t = 10)]
    pub sectors: usize,
    /// Output format.
    #[arg(long, value_enum, default_value_t = Format::Json)]
    pub format: Format,
}

fn parse_list<const N: usize>(s: &str) -> Result<[f64; N], String> {
    let v: Vec<f64> = s
        .split(',')
        .map(|x| x.trim().parse::<f64>().map_err(|e| format!("'{x}': {e}")))
        .collect::<Result<_, _>>()?;
    v.try_into()
        .map_err(|v: Vec<f64>| format!("expected {N} comma-separated numbers, got {}", v.len()))
}

fn parse_cone(s: &str) -> Result<[f64; 4], String> {
    parse_list::<4>(s)
}

fn parse_pair(s: &str) -> Result<[f64; 2], String> {
    parse_list::<2>(s)
}

impl Args {
    /// The direction parameters these arguments describe.
    pub fn params(&self) -> DirectionParams {
        DirectionParams {
            count: self.count,
            cos_weighted: self.cos_weighted,
            layers: self.layers,
            exact: self
                .exact
                .iter()
                .map(|[z, a]| ExactDirection::new(*z, *a))
                .collect(),
            oversample: self
                .oversample_cone
                .iter()
                .map(
                    |&[zenith_deg, azimuth_deg, half_angle_deg, solid_angle_sr]| {
                        OversampleRegion::Cone {
                            zenith_deg,
                            azimuth_deg,
                            half_angle_deg,
                            solid_angle_sr,
                        }
                    },
                )
                .collect(),
            fictive: self
                .fictive
                .iter()
                .map(|[z, a]| ExactDirection::new(*z, *a))
                .collect(),
            exact_solid_angle_sr: self.exact_solid_angle,
            sectors: self.sectors,
        }
    }
}

/// Builds the set and writes it to `out` (errors are messages for the user).
pub fn run(args: &Args, out: &mut dyn std::io::Write) -> Result<(), String> {
    let set = DirectionSet::new(&args.params()).map_err(|e| e.to_string())?;
    let io = |e: std::io::Error| format!("cannot write output: {e}");
    match args.format {
        Format::Csv => {
            writeln!(
                out,
                "index,zenith_deg,azimuth_deg,solid_angle_sr,kind,sector"
            )
            .map_err(io)?;
            for (i, d) in set.directions.iter().enumerate() {
                writeln!(
                    out,
                    "{i},{:.6},{:.6},{:.9e},{},{}",
                    d.zenith_deg(),
                    d.azimuth_deg(),
                    d.solid_angle_sr,
                    d.kind.name(),
                    d.sector
                )
                .map_err(io)?;
            }
        }
        Format::Json => {
            let rows: Vec<serde_json::Value> = set
                .directions
                .iter()
                .enumerate()
                .map(|(i, d)| {
                    serde_json::json!({
                        "index": i,
                        "zenith_deg": d.zenith_deg(),
                        "azimuth_deg": d.azimuth_deg(),
                        "solid_angle_sr": d.solid_angle_sr,
                        "kind": d.kind.name(),
                        "sector": d.sector,
                    })
                })
                .collect();
            serde_json::to_writer_pretty(&mut *out, &rows)
                .map_err(|e| format!("cannot write JSON: {e}"))?;
            writeln!(out).map_err(io)?;
        }
    }
    Ok(())
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

    #[test]
    fn csv_and_json_outputs() {
        let cli = Cli::try_parse_from([
            "x",
            "--count",
            "50",
            "--exact",
            "30,-45",
            "--oversample-cone",
            "30,0,10,0.002",
            "--format",
            "csv",
        ])
        .unwrap();
        let mut buf = Vec::new();
        run(&cli.args, &mut buf).unwrap();
        let text = String::from_utf8(buf).unwrap();
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(
            lines[0],
            "index,zenith_deg,azimuth_deg,solid_angle_sr,kind,sector"
        );
        let total: f64 = lines[1..]
            .iter()
            .map(|l| l.split(',').nth(3).unwrap().parse::<f64>().unwrap())
            .sum();
        assert!((total - 4.0 * std::f64::consts::PI).abs() < 1e-6);
        assert!(text.contains(",exact,") && text.contains(",oversampled,"));
        let cli = Cli::try_parse_from(["x", "--count", "20"]).unwrap();
        let mut buf = Vec::new();
        run(&cli.args, &mut buf).unwrap();
        let v: serde_json::Value = serde_json::from_slice(&buf).unwrap();
        assert_eq!(v.as_array().unwrap().len(), 20);
        let cli = Cli::try_parse_from(["x", "--count", "3"]).unwrap();
        assert!(
            run(&cli.args, &mut Vec::new())
                .unwrap_err()
                .contains("count")
        );
        assert!(Cli::try_parse_from(["x", "--exact", "30"]).is_err());
    }
}
