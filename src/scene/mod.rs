//! The RON scene format: authoring types ([`desc`]), loading with file/line/field errors,
//! validation, the ground's raster input and the programmatic generators (the spawn step that
//! turns a description into entities is ECS glue: `systems/spawn.rs`).

pub mod desc;
pub mod error;
pub mod generators;
pub mod georef;
pub mod landcover;
pub mod locate;
pub mod resolve;
pub mod terrain_input;
pub mod validate;

use desc::SceneDesc;
use error::{Location, SceneError};
use std::path::Path;
pub use validate::SceneSource;

/// Parses RON text into a scene description (syntax, types and unknown fields only).
pub fn parse_scene(text: &str, path: &Path) -> Result<SceneDesc, SceneError> {
    // IMPLICIT_SOME: optional fields take a bare value (`radius_y_m: 2.0`) or `Some(2.0)`.
    ron::Options::default()
        .with_default_extension(ron::extensions::Extensions::IMPLICIT_SOME)
        .from_str::<SceneDesc>(text)
        .map_err(|e| SceneError::Syntax {
            at: Location {
                file: path.to_path_buf(),
                line_col: Some((e.span.start.line, e.span.start.col)),
            },
            message: e.code.to_string(),
        })
}

/// Reads, parses and validates a scene file.
pub fn load_scene(path: &Path) -> Result<(SceneDesc, SceneSource), SceneError> {
    let text = std::fs::read_to_string(path).map_err(|e| SceneError::Io {
        path: path.to_path_buf(),
        source: e,
    })?;
    let desc = parse_scene(&text, path)?;
    let src = SceneSource {
        path: path.to_path_buf(),
        text: Some(text),
    };
    validate::validate(&desc, &src)?;
    Ok((desc, src))
}

/// Serialises a scene as pretty RON (what `lumenscape generate` prints).
pub fn to_ron(desc: &SceneDesc) -> String {
    let cfg = ron::ser::PrettyConfig::default()
        .struct_names(false)
        .depth_limit(5)
        .compact_arrays(true);
    ron::ser::to_string_pretty(desc, cfg).expect("scene descriptions always serialise")
}
