//! Command-line interface: each subcommand is a module with a clap `Args` struct and a `run`
//! function writing to a `Write`, so the binary stays thin and tests can call commands directly.

pub mod directions;
pub mod generate;
pub mod prospect;
pub mod rami;
pub mod scene_cmds;
pub mod sequence;
pub mod sun;
