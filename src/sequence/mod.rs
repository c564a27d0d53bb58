//! Sequences: parameter sweeps and look-up tables (DART's "sequence" tool, DART 5 paper §2).
//!
//! A sequence is a base scene and axes, each setting one scene field (by its path, as in the
//! validation messages) to a list or a range of values; axes combine as a full grid or in
//! zipped groups ([`desc`]). The [`plan`] checks every axis and point before anything runs and
//! splits the points between shards; [`run`] runs a shard's points, each into its own folder,
//! resuming where an interrupted run stopped; [`lut`] gathers the finished points of every
//! shard into one table.
//!
//! From code:
//!
//! ```no_run
//! use lumenscape::scene::generators::turbid_layer::{TurbidLayerParams, turbid_layer};
//! use lumenscape::scene::SceneSource;
//! use lumenscape::sequence::plan::{Axis, Plan, Shard};
//! use lumenscape::resources::scene::RunSettings;
//!
//! let base = turbid_layer(&TurbidLayerParams::default());
//! let plan = Plan::new(base, SceneSource::generated())?
//!     .axis(Axis::new("lai", "objects[1].foliage", &[1.0, 3.0, 5.0])?)
//!     .axis(Axis::new("sza", "illumination.sun_zenith_deg", &[0.0, 30.0])?);
//! plan.check()?;
//! plan.run("out/lut".as_ref(), Shard::ALL, &RunSettings::default())?;
//! lumenscape::sequence::lut::gather("out/lut".as_ref(), "out/lut/lut.csv".as_ref())?;
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

pub mod desc;
pub mod lut;
pub mod merge;
pub mod plan;
pub mod run;
