//! The `lumenscape` command-line tool.

use clap::{Parser, Subcommand};
use lumenscape::cli::{directions, generate, prospect, rami, scene_cmds, sequence, sun};
use std::io::Write;
use std::process::ExitCode;

/// lumenscape: 3D radiative transfer for optical remote sensing (a DART 5 re-implementation).
#[derive(Parser, Debug)]
#[command(name = "lumenscape", version, about, long_about = None)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Validate a scene and print its summary (areas, cells, memory estimate); exit 0 if valid.
    Check(scene_cmds::CheckArgs),
    /// Run the Maket stage and write its products (LAI map, DSM, densities, maket.json).
    Maket(scene_cmds::MaketArgs),
    /// Run every stage that exists so far and write the products.
    Run(scene_cmds::RunArgs),
    /// Run a parameter sweep (sequence file) into a folder, one folder per point; resumable,
    /// shardable across processes and cluster array jobs.
    Sequence(sequence::SequenceArgs),
    /// Gather every finished point of a sequence folder into one look-up table (CSV and Parquet).
    Gather(sequence::GatherArgs),
    /// Print a generated scene as RON.
    Generate(generate::Args),
    /// PROSPECT-5 / PROSPECT-D leaf reflectance and transmittance, 400–2500 nm (CSV).
    Prospect(prospect::Args),
    /// Sun position (NREL SPA) for a date, time and place, in the scene's angle convention.
    Sun(sun::Args),
    /// Print the discrete directions (zenith, azimuth, solid angle, kind, sector) as JSON or CSV.
    Directions(directions::Args),
    /// Convert a finished run into RAMI/ROMC measurement files (.mes) and measurements.json.
    RamiMes(rami::Args),
}

fn plain(message: String) -> scene_cmds::CliError {
    scene_cmds::CliError { message, code: 1 }
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let stdout = std::io::stdout();
    let mut out = stdout.lock();
    let res = match &cli.command {
        Command::Check(a) => scene_cmds::check(a, &mut out),
        Command::Maket(a) => scene_cmds::maket(a, &mut out),
        Command::Run(a) => scene_cmds::run(a, &mut out),
        Command::Sequence(a) => sequence::run(a, &mut out),
        Command::Gather(a) => sequence::gather(a, &mut out),
        Command::Generate(a) => generate::run(a, &mut out),
        Command::Prospect(a) => prospect::run(a, &mut out).map_err(plain),
        Command::Sun(a) => sun::run(a, &mut out).map_err(plain),
        Command::Directions(a) => directions::run(a, &mut out).map_err(plain),
        Command::RamiMes(a) => rami::run(a, &mut out).map_err(plain),
    };
    let _ = out.flush();
    match res {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {}", e.message);
            ExitCode::from(e.code.clamp(1, 255) as u8)
        }
    }
}
