//! Mesh import for the Maket stage: glTF 2.0 (`.gltf`, `.glb`) and Wavefront OBJ (`.obj`).
//!
//! Input: a mesh file named by a scene's imported-mesh object. Output: an [`ImportedMesh`],
//! triangles grouped by material (one [`MeshGroup`] per glTF material / OBJ `usemtl`
//! material), in **the file's own coordinates and units**. The caller (scene spawn / Maket)
//! applies the scene transform with [`ImportedMesh::transform`], cleans degenerate triangles
//! with [`ImportedMesh::clean_triangles`] (and warns with the counts), and maps group names
//! to optical properties.
//!
//! # Coordinates
//! * glTF 2.0 is right-handed and **y-up** (+z is the asset's front, units are metres;
//!   glTF 2.0 specification §3.4). The loader accumulates the node transforms of the
//!   default scene (or of every scene when none is marked default; of every root node when
//!   the file has no scene) but does **not** change the up axis: lumenscape's scene frame is
//!   z-up, so the caller normally pre-multiplies its placement by [`gltf_y_up_to_z_up`].
//! * OBJ has no declared up axis; the loader returns its vertices unchanged. lumenscape's
//!   sample OBJ files are z-up.
//!
//! # Precision
//! Both formats are read as `f32` (glTF stores `f32` positions; tobj parses OBJ into `f32`)
//! and widened to `f64`; node transforms are composed in `f64`.
//!
//! # Front faces
//! Front faces are counter-clockwise (right-hand rule), as in glTF (§3.7.2.1) and OBJ. When
//! a glTF node's accumulated transform, or the matrix given to [`ImportedMesh::transform`],
//! has a negative determinant (a mirror), the vertex order of each triangle is reversed so
//! that front faces stay counter-clockwise (glTF 2.0 specification §3.7.4).
//!
//! # Errors and warnings
//! Every [`MeshError`] names the file. Non-triangle primitives (points, lines) are skipped
//! and counted in [`ImportedMesh::skipped_non_triangle`]; other recoverable oddities (a
//! missing `.mtl`, a `usemtl` naming no known material, a glTF triangle list whose length
//! is not a multiple of three) are described in [`ImportedMesh::warnings`]. Degenerate and
//! non-finite triangles are kept by the loader and removed only by
//! [`ImportedMesh::clean_triangles`], which reports how many it removed.

use std::cell::RefCell;
use std::collections::HashMap;
use std::path::{Path, PathBuf};

use glam::{DMat4, DQuat, DVec3, DVec4};

/// Relative area below which [`ImportedMesh::clean_triangles`] calls a triangle degenerate:
/// a triangle is degenerate when its area is ≤ `DEGENERATE_RELATIVE_AREA · L²`, where `L` is
/// the diagonal of the bounding box of the mesh's finite vertices (so 1e-12 m² for a mesh one
/// metre across, and the test does not depend on the file's length unit).
pub const DEGENERATE_RELATIVE_AREA: f64 = 1e-12;

/// Triangles of one material (or object) of an imported mesh.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct MeshGroup {
    /// Group name: for glTF the material name (`material_<index>` for an unnamed material;
    /// the mesh name for primitives without material; `"default"` if that has no name
    /// either); for OBJ the `usemtl` material name when that material is defined in a
    /// loaded `.mtl`, else the object/group (`o`/`g`) name, else `"default"`. Primitives or
    /// faces with equal names are merged into one group.
    pub name: String,
    /// Triangles `[a, b, c]`, counter-clockwise front face, in the file's coordinates (glTF:
    /// after the node hierarchy) or after [`ImportedMesh::transform`].
    pub triangles: Vec<[DVec3; 3]>,
}

/// A mesh file's triangles, grouped by material. See the module documentation.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ImportedMesh {
    /// Groups in order of first appearance in the file.
    pub groups: Vec<MeshGroup>,
    /// Number of skipped non-triangle primitives: glTF primitives of mode POINTS, LINES,
    /// LINE_LOOP or LINE_STRIP; OBJ `p` and `l` elements and `f` elements with fewer than
    /// three vertices.
    pub skipped_non_triangle: usize,
    /// Human-readable warnings about recoverable problems, for the caller to print.
    pub warnings: Vec<String>,
}

/// What [`ImportedMesh::clean_triangles`] removed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct DegenerateReport {
    /// Triangles with area ≤ [`DEGENERATE_RELATIVE_AREA`]` · L²` (zero-area, collinear or
    /// repeated vertices).
    pub removed_degenerate: usize,
    /// Triangles with a NaN or infinite vertex coordinate, or whose area overflows.
    pub removed_non_finite: usize,
}

impl DegenerateReport {
    /// Total number of removed triangles.
    pub fn removed_total(&self) -> usize {
        self.removed_degenerate + self.removed_non_finite
    }
}

/// Error while importing a mesh file. Each variant names the file.
#[derive(Debug, thiserror::Error)]
pub enum MeshError {
    /// The file does not exist.
    #[error("mesh file {}: not found", path.display())]
    NotFound {
        /// The mesh file.
        path: PathBuf,
    },
    /// The file exists but could not be read.
    #[error("mesh file {}: cannot read: {source}", path.display())]
    Io {
        /// The mesh file.
        path: PathBuf,
        /// The underlying I/O error.
        #[source]
        source: std::io::Error,
    },
    /// The extension is not `.gltf`, `.glb` or `.obj` (case-insensitive).
    #[error(
        "mesh file {}: unsupported extension (expected .gltf, .glb or .obj)",
        path.display()
    )]
    UnsupportedExtension {
        /// The mesh file.
        path: PathBuf,
    },
    /// The file (or an OBJ's `.mtl` library, then named in `path`) is malformed.
    #[error("{}{}: {message}", path.display(), line.map(|l| format!(":{l}")).unwrap_or_default())]
    Parse {
        /// The malformed file.
        path: PathBuf,
        /// 1-based line of the error, for OBJ/MTL files when it is known.
        line: Option<usize>,
        /// What went wrong.
        message: String,
    },
    /// The file parsed but holds no triangle at all.
    #[error("mesh file {}: contains no triangles{detail}", path.display())]
    Empty {
        /// The mesh file.
        path: PathBuf,
        /// Extra context (e.g. how many non-triangle primitives were skipped), may be empty.
        detail: String,
    },
    /// A glTF buffer, buffer view or accessor cannot be read (missing or short `.bin` file,
    /// bad data URI, data out of range, unsupported layout).
    #[error("mesh file {}: bad buffer: {message}", path.display())]
    BadBuffer {
        /// The glTF file.
        path: PathBuf,
        /// What went wrong.
        message: String,
    },
}

impl MeshError {
    /// The file the error is about.
    pub fn path(&self) -> &Path {
        match self {
            MeshError::NotFound { path }
            | MeshError::Io { path, .. }
            | MeshError::UnsupportedExtension { path }
            | MeshError::Parse { path, .. }
            | MeshError::Empty { path, .. }
            | MeshError::BadBuffer { path, .. } => path,
        }
    }
}

/// Area of a triangle, `|(b − a) × (c − a)| / 2`, in the square of the vertices' unit.
pub fn triangle_area(t: &[DVec3; 3]) -> f64 {
    0.5 * (t[1] - t[0]).cross(t[2] - t[0]).length()
}

/// Rotation taking glTF's y-up frame to lumenscape's z-up scene frame: +90° about +x,
/// `(x, y, z) ↦ (x, −z, y)` (glTF +y → +z, glTF front +z → −y; Blender's importer uses the
/// same mapping). Proper rotation (determinant +1). Not applied by [`load_mesh`]; compose it
/// as `world_from_local = placement * gltf_y_up_to_z_up()`.
pub fn gltf_y_up_to_z_up() -> DMat4 {
    DMat4::from_cols(
        DVec4::new(1.0, 0.0, 0.0, 0.0),
        DVec4::new(0.0, 0.0, 1.0, 0.0),
        DVec4::new(0.0, -1.0, 0.0, 0.0),
        DVec4::new(0.0, 0.0, 0.0, 1.0),
    )
}

fn bounds_of<'a>(points: impl Iterator<Item = &'a DVec3>) -> Option<(DVec3, DVec3)> {
    points.fold(None, |acc, &p| match acc {
        None => Some((p, p)),
        Some((lo, hi)) => Some((lo.min(p), hi.max(p))),
    })
}

fn apply_affine(m: &DMat4, p: DVec3) -> DVec3 {
    (*m * p.extend(1.0)).truncate()
}

impl MeshGroup {
    /// Sum of the triangle areas.
    pub fn area(&self) -> f64 {
        self.triangles.iter().map(triangle_area).sum()
    }

    /// Axis-aligned bounding box `(min, max)` of the vertices, `None` without triangles.
    pub fn bounding_box(&self) -> Option<(DVec3, DVec3)> {
        bounds_of(self.triangles.iter().flatten())
    }
}

impl ImportedMesh {
    /// Total number of triangles over all groups.
    pub fn triangle_count(&self) -> usize {
        self.groups.iter().map(|g| g.triangles.len()).sum()
    }

    /// Total triangle area over all groups (square of the coordinates' unit).
    pub fn total_area(&self) -> f64 {
        self.groups.iter().map(MeshGroup::area).sum()
    }

    /// The group with this name, if any.
    pub fn group(&self, name: &str) -> Option<&MeshGroup> {
        self.groups.iter().find(|g| g.name == name)
    }

    /// Axis-aligned bounding box `(min, max)` of all vertices, `None` without triangles.
    pub fn bounding_box(&self) -> Option<(DVec3, DVec3)> {
        bounds_of(
            self.groups
                .iter()
                .flat_map(|g| g.triangles.iter().flatten()),
        )
    }

    /// Maps every vertex by the affine matrix `world_from_local` (its last row is ignored,
    /// i.e. taken as `(0, 0, 0, 1)`). If the matrix mirrors (negative determinant), each
    /// triangle's vertex order is reversed so front faces stay counter-clockwise.
    pub fn transform(&mut self, world_from_local: DMat4) {
        let mirror = world_from_local.determinant() < 0.0;
        for g in &mut self.groups {
            for t in &mut g.triangles {
                for p in t.iter_mut() {
                    *p = apply_affine(&world_from_local, *p);
                }
                if mirror {
                    t.swap(1, 2);
                }
            }
        }
    }

    /// Removes triangles with a non-finite vertex (or non-finite area), then triangles whose
    /// area is ≤ [`DEGENERATE_RELATIVE_AREA`]` · L²` with `L` the bounding-box diagonal of
    /// the remaining vertices, and reports the counts. Groups left empty are kept (with no
    /// triangles) so group-to-optics mappings stay valid; check [`Self::triangle_count`].
    pub fn clean_triangles(&mut self) -> DegenerateReport {
        let mut report = DegenerateReport::default();
        for g in &mut self.groups {
            let before = g.triangles.len();
            g.triangles
                .retain(|t| t.iter().all(|p| p.is_finite()) && triangle_area(t).is_finite());
            report.removed_non_finite += before - g.triangles.len();
        }
        let diagonal = self
            .bounding_box()
            .map(|(lo, hi)| (hi - lo).length())
            .unwrap_or(0.0);
        let threshold = DEGENERATE_RELATIVE_AREA * diagonal * diagonal;
        for g in &mut self.groups {
            let before = g.triangles.len();
            g.triangles.retain(|t| triangle_area(t) > threshold);
            report.removed_degenerate += before - g.triangles.len();
        }
        report
    }
}

/// Collects triangles into groups merged by name, in order of first appearance.
#[derive(Default)]
struct GroupSink {
    mesh: ImportedMesh,
    index: HashMap<String, usize>,
}

impl GroupSink {
    fn group(&mut self, name: &str) -> &mut Vec<[DVec3; 3]> {
        let i = match self.index.get(name) {
            Some(&i) => i,
            None => {
                self.mesh.groups.push(MeshGroup {
                    name: name.to_owned(),
                    triangles: Vec::new(),
                });
                self.index
                    .insert(name.to_owned(), self.mesh.groups.len() - 1);
                self.mesh.groups.len() - 1
            }
        };
        &mut self.mesh.groups[i].triangles
    }

    fn finish(self, path: &Path) -> Result<ImportedMesh, MeshError> {
        if self.mesh.triangle_count() == 0 {
            let detail = if self.mesh.skipped_non_triangle > 0 {
                format!(
                    " ({} non-triangle primitives skipped)",
                    self.mesh.skipped_non_triangle
                )
            } else {
                String::new()
            };
            return Err(MeshError::Empty {
                path: path.to_owned(),
                detail,
            });
        }
        Ok(self.mesh)
    }
}

/// Loads a `.gltf`, `.glb` or `.obj` file (extension case-insensitive) into triangles grouped
/// by material, in the file's own coordinates (see the module documentation: glTF node
/// transforms are applied, the y-up axis is not changed). Degenerate triangles are kept;
/// call [`ImportedMesh::clean_triangles`].
///
/// # Errors
/// [`MeshError`] naming the file: unsupported extension, missing or unreadable file,
/// malformed content (with the line for OBJ/MTL), unreadable glTF buffers, or no triangle.
pub fn load_mesh(path: &Path) -> Result<ImportedMesh, MeshError> {
    #[derive(PartialEq)]
    enum Kind {
        Gltf,
        Glb,
        Obj,
    }
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    let kind = match ext.as_deref() {
        Some("gltf") => Kind::Gltf,
        Some("glb") => Kind::Glb,
        Some("obj") => Kind::Obj,
        _ => {
            return Err(MeshError::UnsupportedExtension {
                path: path.to_owned(),
            });
        }
    };
    let bytes = std::fs::read(path).map_err(|e| {
        if e.kind() == std::io::ErrorKind::NotFound {
            MeshError::NotFound {
                path: path.to_owned(),
            }
        } else {
            MeshError::Io {
                path: path.to_owned(),
                source: e,
            }
        }
    })?;
    match kind {
        Kind::Obj => load_obj(path, &bytes),
        Kind::Gltf | Kind::Glb => load_gltf(path, &bytes, kind == Kind::Glb),
    }
}

// ------------------------------------------------------------------------------------- glTF

fn parse_err(path: &Path, line: Option<usize>, message: impl Into<String>) -> MeshError {
    MeshError::Parse {
        path: path.to_owned(),
        line,
        message: message.into(),
    }
}

fn buffer_err(path: &Path, message: impl Into<String>) -> MeshError {
    MeshError::BadBuffer {
        path: path.to_owned(),
        message: message.into(),
    }
}

/// GLB header (magic, version, total length: glTF 2.0 §4.4.3) checked before the gltf crate
/// parses it, so malformed lengths give errors rather than arithmetic overflow.
fn check_glb_header(path: &Path, bytes: &[u8]) -> Result<(), MeshError> {
    if bytes.len() < 20 {
        return Err(parse_err(
            path,
            None,
            format!(
                "binary glTF is truncated: {} bytes, a GLB header and chunk header need 20",
                bytes.len()
            ),
        ));
    }
    let word = |i: usize| u32::from_le_bytes([bytes[i], bytes[i + 1], bytes[i + 2], bytes[i + 3]]);
    let (version, length) = (word(4), word(8) as usize);
    if version != 2 {
        return Err(parse_err(
            path,
            None,
            format!("binary glTF version {version} is not supported (expected 2)"),
        ));
    }
    if length < 20 || length > bytes.len() {
        return Err(parse_err(
            path,
            None,
            format!(
                "binary glTF header declares {length} bytes but the file has {} (truncated or corrupt)",
                bytes.len()
            ),
        ));
    }
    Ok(())
}

fn load_gltf(path: &Path, bytes: &[u8], glb_extension: bool) -> Result<ImportedMesh, MeshError> {
    let is_glb = bytes.starts_with(b"glTF");
    if glb_extension && !is_glb {
        return Err(parse_err(
            path,
            None,
            "not a binary glTF file (missing the 'glTF' magic bytes)",
        ));
    }
    if is_glb {
        check_glb_header(path, bytes)?;
    }
    let gltf = parse_and_validate_gltf(path, bytes)?;
    let buffers = load_buffers(path, &gltf)?;
    check_node_forest(path, &gltf)?;

    let roots: Vec<gltf::Node> = if let Some(scene) = gltf.default_scene() {
        scene.nodes().collect()
    } else if gltf.scenes().len() > 0 {
        gltf.scenes().flat_map(|s| s.nodes()).collect()
    } else {
        let mut is_child = vec![false; gltf.nodes().len()];
        for n in gltf.nodes() {
            for c in n.children() {
                is_child[c.index()] = true;
            }
        }
        gltf.nodes().filter(|n| !is_child[n.index()]).collect()
    };

    let mut sink = GroupSink::default();
    let mut stack: Vec<(gltf::Node, DMat4)> =
        roots.into_iter().map(|n| (n, DMat4::IDENTITY)).collect();
    while let Some((node, parent)) = stack.pop() {
        let world = parent * node_matrix(path, &node)?;
        if let Some(mesh) = node.mesh() {
            for prim in mesh.primitives() {
                import_primitive(path, &buffers, &mesh, &prim, &world, &mut sink)?;
            }
        }
        // Reverse so siblings are visited in file order (stack is LIFO).
        let children: Vec<_> = node.children().collect();
        for child in children.into_iter().rev() {
            stack.push((child, world));
        }
    }
    sink.finish(path)
}

/// Parses and validates a glTF document. Attribute accessor indices are checked before the
/// gltf crate's validation, which indexes the POSITION accessor unchecked (gltf-json 1.4.1
/// `primitive_validate_hook`) and would panic on an out-of-range index.
fn parse_and_validate_gltf(path: &Path, bytes: &[u8]) -> Result<gltf::Gltf, MeshError> {
    let invalid = |e: gltf::Error| parse_err(path, None, format!("invalid glTF: {e}"));
    let unvalidated = gltf::Gltf::from_slice_without_validation(bytes).map_err(invalid)?;
    let json = unvalidated.document.into_json();
    for (m, mesh) in json.meshes.iter().enumerate() {
        for (p, prim) in mesh.primitives.iter().enumerate() {
            for index in prim.attributes.values() {
                if index.value() >= json.accessors.len() {
                    return Err(parse_err(
                        path,
                        None,
                        format!(
                            "invalid glTF: mesh {m} primitive {p} refers to accessor {} but \
                             there are {} accessors",
                            index.value(),
                            json.accessors.len()
                        ),
                    ));
                }
            }
        }
    }
    let document = gltf::Document::from_json(json).map_err(invalid)?;
    Ok(gltf::Gltf {
        document,
        blob: unvalidated.blob,
    })
}

/// glTF requires the node hierarchy to be a set of disjoint strict trees (§3.5.3); check
/// it (each node has at most one parent, no cycle) so traversal terminates.
fn check_node_forest(path: &Path, gltf: &gltf::Gltf) -> Result<(), MeshError> {
    let n = gltf.nodes().len();
    let mut parent: Vec<Option<usize>> = vec![None; n];
    for node in gltf.nodes() {
        for child in node.children() {
            let c = child.index();
            if parent[c].is_some() || c == node.index() {
                return Err(parse_err(
                    path,
                    None,
                    format!("invalid glTF: node {c} has more than one parent or is its own child"),
                ));
            }
            parent[c] = Some(node.index());
        }
    }
    for start in 0..n {
        let (mut cur, mut steps) = (start, 0);
        while let Some(p) = parent[cur] {
            cur = p;
            steps += 1;
            if steps > n {
                return Err(parse_err(
                    path,
                    None,
                    format!("invalid glTF: the node hierarchy has a cycle through node {start}"),
                ));
            }
        }
    }
    Ok(())
}

fn node_matrix(path: &Path, node: &gltf::Node) -> Result<DMat4, MeshError> {
    let m = match node.transform() {
        gltf::scene::Transform::Matrix { matrix } => {
            DMat4::from_cols_array_2d(&matrix.map(|c| c.map(f64::from)))
        }
        gltf::scene::Transform::Decomposed {
            translation,
            rotation,
            scale,
        } => {
            let q = DQuat::from_array(rotation.map(f64::from));
            let len = q.length();
            if !(len.is_finite() && len > 0.0) {
                return Err(parse_err(
                    path,
                    None,
                    format!(
                        "node {} has an invalid rotation quaternion {rotation:?}",
                        node.index()
                    ),
                ));
            }
            DMat4::from_scale_rotation_translation(
                DVec3::from_array(scale.map(f64::from)),
                q / len,
                DVec3::from_array(translation.map(f64::from)),
            )
        }
    };
    if !m.is_finite() {
        return Err(parse_err(
            path,
            None,
            format!("node {} has a non-finite transform", node.index()),
        ));
    }
    Ok(m)
}

/// Decodes a `data:[<media type>];base64,<data>` URI (RFC 2397) holding a buffer.
fn decode_data_uri(uri: &str) -> Result<Vec<u8>, String> {
    use base64::Engine;
    let rest = uri
        .strip_prefix("data:")
        .ok_or_else(|| "not a data URI".to_owned())?;
    let (header, data) = rest
        .split_once(',')
        .ok_or_else(|| "data URI has no ',' before its payload".to_owned())?;
    let media = header.strip_suffix(";base64").ok_or_else(|| {
        format!("data URI 'data:{header},…' is not base64-encoded (';base64' missing)")
    })?;
    if !matches!(
        media,
        "" | "application/octet-stream" | "application/gltf-buffer"
    ) {
        return Err(format!(
            "data URI media type '{media}' is not a buffer (expected application/octet-stream)"
        ));
    }
    base64::engine::general_purpose::STANDARD_PAD_INDIFFERENT
        .decode(data)
        .map_err(|e| format!("invalid base64 in data URI: {e}"))
}

/// Decodes `%XX` escapes of a relative URI reference into a path string.
fn percent_decode(uri: &str) -> Result<String, String> {
    let bytes = uri.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        if bytes[i] == b'%' {
            let hex = bytes
                .get(i + 1..i + 3)
                .and_then(|h| std::str::from_utf8(h).ok())
                .and_then(|h| u8::from_str_radix(h, 16).ok())
                .ok_or_else(|| format!("bad percent escape in URI '{uri}'"))?;
            out.push(hex);
            i += 3;
        } else {
            out.push(bytes[i]);
            i += 1;
        }
    }
    String::from_utf8(out).map_err(|_| format!("URI '{uri}' does not decode to UTF-8"))
}

fn load_buffers(path: &Path, gltf: &gltf::Gltf) -> Result<Vec<Vec<u8>>, MeshError> {
    let dir = path.parent().unwrap_or(Path::new("."));
    let mut out = Vec::new();
    for buffer in gltf.buffers() {
        let i = buffer.index();
        let data = match buffer.source() {
            gltf::buffer::Source::Bin => gltf.blob.clone().ok_or_else(|| {
                buffer_err(
                    path,
                    format!("buffer {i} refers to the GLB binary chunk, but the file has none"),
                )
            })?,
            gltf::buffer::Source::Uri(uri) if uri.starts_with("data:") => {
                decode_data_uri(uri).map_err(|m| buffer_err(path, format!("buffer {i}: {m}")))?
            }
            gltf::buffer::Source::Uri(uri) => {
                let scheme = uri
                    .find(':')
                    .is_some_and(|c| !uri[..c].contains('/') && c > 1);
                if scheme {
                    return Err(buffer_err(
                        path,
                        format!(
                            "buffer {i}: URI '{uri}' is not supported (only relative file paths \
                             and base64 data URIs)"
                        ),
                    ));
                }
                let rel = percent_decode(uri)
                    .map_err(|m| buffer_err(path, format!("buffer {i}: {m}")))?;
                let file = dir.join(rel);
                std::fs::read(&file).map_err(|e| {
                    buffer_err(
                        path,
                        format!(
                            "buffer {i}: cannot read external file {}: {e}",
                            file.display()
                        ),
                    )
                })?
            }
        };
        if data.len() < buffer.length() {
            return Err(buffer_err(
                path,
                format!(
                    "buffer {i} declares byteLength {} but holds only {} bytes",
                    buffer.length(),
                    data.len()
                ),
            ));
        }
        out.push(data);
    }
    Ok(out)
}

/// Checks that an accessor can be read by the gltf crate's reader without going out of
/// range (the reader would panic on zero counts, strides smaller than an element or invalid
/// component types, which a validated document may still contain).
fn check_accessor(
    acc: &gltf::Accessor,
    buffers: &[Vec<u8>],
    allowed: &[gltf::accessor::DataType],
    dims: gltf::accessor::Dimensions,
) -> Result<(), String> {
    let i = acc.index();
    if acc.sparse().is_some() {
        return Err(format!("accessor {i} is sparse, which is not supported"));
    }
    if !allowed.contains(&acc.data_type()) || acc.dimensions() != dims {
        return Err(format!(
            "accessor {i} is {:?} {:?}, expected {dims:?} of {allowed:?}",
            acc.dimensions(),
            acc.data_type()
        ));
    }
    if acc.count() == 0 {
        return Err(format!("accessor {i} has count 0"));
    }
    let view = acc
        .view()
        .ok_or_else(|| format!("accessor {i} has no buffer view"))?;
    let elem = acc.size();
    let stride = view.stride().unwrap_or(elem);
    if stride < elem {
        return Err(format!(
            "accessor {i}: byte stride {stride} is smaller than its element ({elem} bytes)"
        ));
    }
    let end = stride
        .checked_mul(acc.count() - 1)
        .and_then(|x| x.checked_add(elem))
        .and_then(|x| x.checked_add(acc.offset()));
    if end.is_none_or(|e| e > view.length()) {
        return Err(format!(
            "accessor {i} ({} elements) reads past the end of buffer view {}",
            acc.count(),
            view.index()
        ));
    }
    let view_end = view.offset().checked_add(view.length());
    let data_len = buffers.get(view.buffer().index()).map_or(0, Vec::len);
    if view_end.is_none_or(|e| e > data_len) {
        return Err(format!(
            "buffer view {} reads past the end of buffer {}",
            view.index(),
            view.buffer().index()
        ));
    }
    Ok(())
}

/// Expands a primitive's vertex sequence into triangles (glTF 2.0 §3.7.2.1):
/// TRIANGLES `{v₃ᵢ, v₃ᵢ₊₁, v₃ᵢ₊₂}`; TRIANGLE_STRIP `{vᵢ, vᵢ₊₍₁₊ᵢ﹪₂₎, vᵢ₊₍₂₋ᵢ﹪₂₎}`;
/// TRIANGLE_FAN `{vᵢ₊₁, vᵢ₊₂, v₀}`. Returns `None` for non-triangle modes.
fn expand_primitive(mode: gltf::mesh::Mode, seq: &[u32]) -> Option<Vec<[u32; 3]>> {
    use gltf::mesh::Mode;
    let n = seq.len();
    Some(match mode {
        Mode::Triangles => seq.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect(),
        Mode::TriangleStrip => (0..n.saturating_sub(2))
            .map(|i| {
                if i % 2 == 0 {
                    [seq[i], seq[i + 1], seq[i + 2]]
                } else {
                    [seq[i], seq[i + 2], seq[i + 1]]
                }
            })
            .collect(),
        Mode::TriangleFan => (0..n.saturating_sub(2))
            .map(|i| [seq[i + 1], seq[i + 2], seq[0]])
            .collect(),
        Mode::Points | Mode::Lines | Mode::LineLoop | Mode::LineStrip => return None,
    })
}

fn import_primitive(
    path: &Path,
    buffers: &[Vec<u8>],
    mesh: &gltf::Mesh,
    prim: &gltf::Primitive,
    world: &DMat4,
    sink: &mut GroupSink,
) -> Result<(), MeshError> {
    use gltf::accessor::{DataType, Dimensions};
    use gltf::mesh::Mode;
    let what = format!("mesh {} primitive {}", mesh.index(), prim.index());
    if !matches!(
        prim.mode(),
        Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan
    ) {
        sink.mesh.skipped_non_triangle += 1;
        return Ok(());
    }
    let pos_acc = prim
        .get(&gltf::Semantic::Positions)
        .ok_or_else(|| parse_err(path, None, format!("{what} has no POSITION attribute")))?;
    check_accessor(&pos_acc, buffers, &[DataType::F32], Dimensions::Vec3)
        .map_err(|m| buffer_err(path, format!("{what}: {m}")))?;
    let reader = prim.reader(|b| buffers.get(b.index()).map(Vec::as_slice));
    let positions: Vec<DVec3> = reader
        .read_positions()
        .ok_or_else(|| buffer_err(path, format!("{what}: cannot read positions")))?
        .map(|p| apply_affine(world, DVec3::from_array(p.map(f64::from))))
        .collect();
    if positions.len() != pos_acc.count() {
        return Err(buffer_err(
            path,
            format!(
                "{what}: read {} positions, accessor declares {}",
                positions.len(),
                pos_acc.count()
            ),
        ));
    }
    let seq: Vec<u32> = match prim.indices() {
        Some(idx_acc) => {
            check_accessor(
                &idx_acc,
                buffers,
                &[DataType::U8, DataType::U16, DataType::U32],
                Dimensions::Scalar,
            )
            .map_err(|m| buffer_err(path, format!("{what}: indices: {m}")))?;
            let seq: Vec<u32> = reader
                .read_indices()
                .ok_or_else(|| buffer_err(path, format!("{what}: cannot read indices")))?
                .into_u32()
                .collect();
            if let Some(&bad) = seq.iter().find(|&&i| i as usize >= positions.len()) {
                return Err(buffer_err(
                    path,
                    format!(
                        "{what}: index {bad} out of range ({} vertices)",
                        positions.len()
                    ),
                ));
            }
            seq
        }
        None => {
            let n = u32::try_from(positions.len()).map_err(|_| {
                buffer_err(
                    path,
                    format!("{what}: too many vertices for 32-bit indexing"),
                )
            })?;
            (0..n).collect()
        }
    };
    if prim.mode() == Mode::Triangles && !seq.len().is_multiple_of(3) {
        sink.mesh.warnings.push(format!(
            "{}: {what}: {} vertices in a triangle list is not a multiple of 3; the last {} ignored",
            path.display(),
            seq.len(),
            seq.len() % 3
        ));
    }
    let tris = expand_primitive(prim.mode(), &seq).unwrap_or_default();
    let mirror = world.determinant() < 0.0;
    let material = prim.material();
    let name = match material.index() {
        Some(i) => material
            .name()
            .map(str::to_owned)
            .unwrap_or_else(|| format!("material_{i}")),
        None => mesh.name().unwrap_or("default").to_owned(),
    };
    let group = sink.group(&name);
    group.extend(tris.into_iter().map(|[a, b, c]| {
        let (a, b, c) = (
            positions[a as usize],
            positions[b as usize],
            positions[c as usize],
        );
        if mirror { [a, c, b] } else { [a, b, c] }
    }));
    Ok(())
}

// -------------------------------------------------------------------------------------- OBJ

/// A `BufRead` over a byte slice that tracks how many lines have been consumed, so that a
/// tobj error (which carries no position) can be reported with the line being parsed.
struct LineCounter<'a> {
    data: &'a [u8],
    pos: usize,
    newlines: usize,
}

impl<'a> LineCounter<'a> {
    fn new(data: &'a [u8]) -> Self {
        Self {
            data,
            pos: 0,
            newlines: 0,
        }
    }

    /// 1-based number of the last line handed out (the one being parsed).
    fn current_line(&self) -> usize {
        if self.pos > 0 && self.data[self.pos - 1] == b'\n' {
            self.newlines.max(1)
        } else {
            self.newlines + 1
        }
    }
}

impl std::io::Read for LineCounter<'_> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let n = buf.len().min(self.data.len() - self.pos);
        buf[..n].copy_from_slice(&self.data[self.pos..self.pos + n]);
        std::io::BufRead::consume(self, n);
        Ok(n)
    }
}

impl std::io::BufRead for LineCounter<'_> {
    fn fill_buf(&mut self) -> std::io::Result<&[u8]> {
        Ok(&self.data[self.pos..])
    }

    fn consume(&mut self, amt: usize) {
        let end = (self.pos + amt).min(self.data.len());
        self.newlines += self.data[self.pos..end]
            .iter()
            .filter(|&&b| b == b'\n')
            .count();
        self.pos = end;
    }
}

/// What a pre-pass over the OBJ text finds before tobj parses it.
struct ObjScan {
    skipped_non_triangle: usize,
    /// `usemtl` names with the line of their first use.
    usemtl: Vec<(String, usize)>,
}

/// Pre-pass over an OBJ file: reports invalid UTF-8 and face indices that are zero or refer
/// to elements not defined before the face (OBJ spec; tobj would otherwise detect them late,
/// without a line, or overflow), and counts the point/line elements that will be skipped.
fn scan_obj(path: &Path, bytes: &[u8]) -> Result<ObjScan, MeshError> {
    let mut scan = ObjScan {
        skipped_non_triangle: 0,
        usemtl: Vec::new(),
    };
    let mut counts = [0usize; 3]; // v, vt, vn defined so far
    const KINDS: [&str; 3] = ["vertex", "texture coordinate", "normal"];
    for (i, raw) in bytes.split(|&b| b == b'\n').enumerate() {
        let line_no = i + 1;
        let line = std::str::from_utf8(raw)
            .map_err(|_| parse_err(path, Some(line_no), "line is not valid UTF-8 text"))?;
        let mut words = line.split_whitespace();
        match words.next() {
            Some("v") => counts[0] += 1,
            Some("vt") => counts[1] += 1,
            Some("vn") => counts[2] += 1,
            Some("p") | Some("l") => scan.skipped_non_triangle += 1,
            Some("usemtl") => {
                let name = line
                    .trim_start()
                    .split_once(' ')
                    .unwrap_or_default()
                    .1
                    .trim();
                if !scan.usemtl.iter().any(|(n, _)| n == name) {
                    scan.usemtl.push((name.to_owned(), line_no));
                }
            }
            Some("f") => {
                let mut n_vertices = 0;
                for token in words {
                    n_vertices += 1;
                    let parts: Vec<&str> = token.split('/').collect();
                    if parts.len() > 3 || parts[0].is_empty() {
                        return Err(parse_err(
                            path,
                            Some(line_no),
                            format!("malformed face vertex '{token}'"),
                        ));
                    }
                    for (k, part) in parts.iter().enumerate() {
                        if part.is_empty() {
                            continue;
                        }
                        let x: isize = part.parse().map_err(|_| {
                            parse_err(
                                path,
                                Some(line_no),
                                format!("malformed face vertex '{token}'"),
                            )
                        })?;
                        if x == 0 || x.unsigned_abs() > counts[k] {
                            return Err(parse_err(
                                path,
                                Some(line_no),
                                format!(
                                    "face refers to {} {x}, but {} {}s are defined before this line",
                                    KINDS[k], counts[k], KINDS[k]
                                ),
                            ));
                        }
                    }
                }
                match n_vertices {
                    0 => return Err(parse_err(path, Some(line_no), "face without vertices")),
                    1 | 2 => scan.skipped_non_triangle += 1,
                    _ => {}
                }
            }
            _ => {}
        }
    }
    Ok(scan)
}

/// Material names declared by `newmtl` in an MTL library, in file order. Only the names
/// are needed (lumenscape takes optics from the scene, not from MTL colours), and reading
/// them here rather than with tobj's MTL parser avoids its panic on `Kd` lines with fewer
/// than three numbers (tobj 4.0.5 `parse_float3`).
fn mtl_material_names(path: &Path, bytes: &[u8]) -> Result<Vec<String>, MeshError> {
    let mut names = Vec::new();
    for (i, raw) in bytes.split(|&b| b == b'\n').enumerate() {
        let line = std::str::from_utf8(raw)
            .map_err(|_| parse_err(path, Some(i + 1), "line is not valid UTF-8 text"))?
            .trim();
        let mut words = line.split_whitespace();
        if words.next() == Some("newmtl") {
            let name = line["newmtl".len()..].trim();
            if name.is_empty() {
                return Err(parse_err(
                    path,
                    Some(i + 1),
                    "newmtl without a material name",
                ));
            }
            names.push(name.to_owned());
        }
    }
    Ok(names)
}

fn tobj_message(e: &tobj::LoadError) -> String {
    format!("OBJ parse error: {e}")
}

fn load_obj(path: &Path, bytes: &[u8]) -> Result<ImportedMesh, MeshError> {
    let scan = scan_obj(path, bytes)?;
    let dir = path.parent().unwrap_or(Path::new(".")).to_owned();
    let mtl_warnings = RefCell::new(Vec::<String>::new());
    let mtl_error = RefCell::new(None::<MeshError>);
    let material_loader = |p: &Path| -> tobj::MTLLoadResult {
        let file = dir.join(p);
        let mut result: tobj::MTLLoadResult = Ok(Default::default());
        match std::fs::read(&file) {
            Err(e) => mtl_warnings.borrow_mut().push(format!(
                "{}: material library {} cannot be read ({e}); faces are grouped by object name",
                path.display(),
                file.display()
            )),
            Ok(mtl_bytes) => match mtl_material_names(&file, &mtl_bytes) {
                Ok(names) => {
                    if let Ok((materials, index)) = &mut result {
                        for name in names {
                            index.insert(name.clone(), materials.len());
                            materials.push(tobj::Material {
                                name,
                                ..Default::default()
                            });
                        }
                    }
                }
                Err(e) => {
                    mtl_error.borrow_mut().get_or_insert(e);
                    result = Err(tobj::LoadError::MaterialParseError);
                }
            },
        }
        result
    };
    // `..Default::default()` covers the fields of tobj's optional `merging`/`reordering`
    // features, should another crate enable them.
    #[allow(clippy::needless_update)]
    let options = tobj::LoadOptions {
        triangulate: true,
        ignore_points: true,
        ignore_lines: true,
        single_index: false,
        ..Default::default()
    };
    let mut reader = LineCounter::new(bytes);
    let result = tobj::load_obj_buf(&mut reader, &options, material_loader);
    if let Some(e) = mtl_error.into_inner() {
        return Err(e);
    }
    let (models, materials) = result.map_err(|e| match e {
        // Detected when a group is closed, not at the offending line.
        tobj::LoadError::InvalidPolygon
        | tobj::LoadError::FaceVertexOutOfBounds
        | tobj::LoadError::FaceTexCoordOutOfBounds
        | tobj::LoadError::FaceNormalOutOfBounds
        | tobj::LoadError::FaceColorOutOfBounds => parse_err(
            path,
            None,
            format!(
                "{} (in the group ending at line {})",
                tobj_message(&e),
                reader.current_line()
            ),
        ),
        _ => parse_err(path, Some(reader.current_line()), tobj_message(&e)),
    })?;
    let materials = materials.unwrap_or_default();

    let mut sink = GroupSink::default();
    sink.mesh.skipped_non_triangle = scan.skipped_non_triangle;
    sink.mesh.warnings = mtl_warnings.into_inner();
    for (name, line) in &scan.usemtl {
        if !materials.iter().any(|m| &m.name == name) {
            sink.mesh.warnings.push(format!(
                "{}:{line}: usemtl '{name}' names no material of a loaded .mtl; its faces are \
                 grouped by object name",
                path.display()
            ));
        }
    }
    for model in &models {
        let m = &model.mesh;
        let name = match m.material_id.and_then(|i| materials.get(i)) {
            Some(mat) => mat.name.clone(),
            None if model.name.is_empty() => "default".to_owned(),
            None => model.name.clone(),
        };
        let vertex = |i: u32| -> Option<DVec3> {
            let k = 3 * i as usize;
            m.positions
                .get(k..k + 3)
                .map(|p| DVec3::new(f64::from(p[0]), f64::from(p[1]), f64::from(p[2])))
        };
        let mut tris = Vec::with_capacity(m.indices.len() / 3);
        for c in m.indices.chunks_exact(3) {
            match (vertex(c[0]), vertex(c[1]), vertex(c[2])) {
                (Some(a), Some(b), Some(c)) => tris.push([a, b, c]),
                _ => {
                    return Err(parse_err(
                        path,
                        None,
                        format!("object '{}' has a face index out of range", model.name),
                    ));
                }
            }
        }
        if !tris.is_empty() {
            sink.group(&name).extend(tris);
        }
    }
    sink.finish(path)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tri(a: [f64; 3], b: [f64; 3], c: [f64; 3]) -> [DVec3; 3] {
        [DVec3::from(a), DVec3::from(b), DVec3::from(c)]
    }

    fn signed_volume(tris: &[[DVec3; 3]]) -> f64 {
        tris.iter().map(|t| t[0].dot(t[1].cross(t[2]))).sum::<f64>() / 6.0
    }

    #[test]
    fn triangle_area_of_right_triangle() {
        let t = tri([0.0, 0.0, 0.0], [3.0, 0.0, 0.0], [0.0, 4.0, 0.0]);
        assert_eq!(triangle_area(&t), 6.0);
    }

    #[test]
    fn strip_and_fan_follow_gltf_spec() {
        use gltf::mesh::Mode;
        let seq = [0, 1, 2, 3, 4];
        assert_eq!(
            expand_primitive(Mode::TriangleStrip, &seq).unwrap(),
            vec![[0, 1, 2], [1, 3, 2], [2, 3, 4]]
        );
        assert_eq!(
            expand_primitive(Mode::TriangleFan, &seq).unwrap(),
            vec![[1, 2, 0], [2, 3, 0], [3, 4, 0]]
        );
        assert_eq!(
            expand_primitive(Mode::Triangles, &[0, 1, 2, 3, 4, 5, 6]).unwrap(),
            vec![[0, 1, 2], [3, 4, 5]]
        );
        assert!(
            expand_primitive(Mode::Triangles, &[0, 1])
                .unwrap()
                .is_empty()
        );
        assert!(
            expand_primitive(Mode::TriangleStrip, &[0, 1])
                .unwrap()
                .is_empty()
        );
        assert!(expand_primitive(Mode::Lines, &seq).is_none());
        assert!(expand_primitive(Mode::Points, &seq).is_none());
    }

    #[test]
    fn strip_keeps_consistent_winding() {
        // A planar strip over a zig-zag in the z = 0 plane: every triangle must face +z.
        let pts: Vec<DVec3> = (0..8)
            .map(|i| DVec3::new((i / 2) as f64, (i % 2) as f64, 0.0))
            .collect();
        let seq: Vec<u32> = (0..8).collect();
        for [a, b, c] in expand_primitive(gltf::mesh::Mode::TriangleStrip, &seq).unwrap() {
            let (a, b, c) = (pts[a as usize], pts[b as usize], pts[c as usize]);
            let n = (b - a).cross(c - a);
            // (0,0),(0,1),(1,0): clockwise seen from +z, so every strip triangle faces −z.
            assert!(n.z < 0.0 && n.x == 0.0 && n.y == 0.0, "normal {n}");
        }
    }

    #[test]
    fn y_up_to_z_up_maps_axes() {
        let m = gltf_y_up_to_z_up();
        assert_eq!(m.transform_point3(DVec3::Y), DVec3::Z);
        assert_eq!(m.transform_point3(DVec3::Z), -DVec3::Y);
        assert_eq!(m.transform_point3(DVec3::X), DVec3::X);
        assert_eq!(m.determinant(), 1.0);
    }

    #[test]
    fn transform_moves_vertices_and_mirror_keeps_orientation() {
        // Unit right tetrahedron, outward-facing: signed volume +1/6.
        let o = [0.0, 0.0, 0.0];
        let (x, y, z) = ([1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]);
        let tets = vec![tri(o, y, x), tri(o, x, z), tri(o, z, y), tri(x, y, z)];
        let mut mesh = ImportedMesh {
            groups: vec![MeshGroup {
                name: "t".into(),
                triangles: tets,
            }],
            ..Default::default()
        };
        assert!((signed_volume(&mesh.groups[0].triangles) - 1.0 / 6.0).abs() < 1e-15);
        mesh.transform(DMat4::from_translation(DVec3::new(5.0, 0.0, 0.0)));
        assert!((signed_volume(&mesh.groups[0].triangles) - 1.0 / 6.0).abs() < 1e-14);
        let (lo, hi) = mesh.bounding_box().unwrap();
        assert_eq!(
            (lo, hi),
            (DVec3::new(5.0, 0.0, 0.0), DVec3::new(6.0, 1.0, 1.0))
        );
        // Mirror x → −x (det −1) and scale by 2 (det −8): volume 8/6, still positive.
        mesh.transform(DMat4::from_scale(DVec3::new(-2.0, 2.0, 2.0)));
        let v = signed_volume(&mesh.groups[0].triangles);
        assert!((v - 8.0 / 6.0).abs() < 1e-13, "signed volume {v}");
        assert!((mesh.total_area() - 4.0 * (1.5 + 3f64.sqrt() / 2.0)).abs() < 1e-13);
    }

    #[test]
    fn clean_counts_degenerate_and_non_finite() {
        let good = tri([0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]);
        let repeated = tri([0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 0.0, 0.0]);
        let collinear = tri([0.0, 0.0, 0.0], [0.5, 0.5, 0.5], [1.0, 1.0, 1.0]);
        let point = tri([2.0, 2.0, 2.0], [2.0, 2.0, 2.0], [2.0, 2.0, 2.0]);
        // Area 5e-14 in a mesh whose bbox diagonal is about 3.46: threshold 1.2e-11.
        let sliver = tri([0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1e-13, 0.0]);
        let nan = tri([f64::NAN, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]);
        let inf = tri([0.0, 0.0, 0.0], [f64::INFINITY, 0.0, 0.0], [0.0, 1.0, 0.0]);
        let mut mesh = ImportedMesh {
            groups: vec![
                MeshGroup {
                    name: "a".into(),
                    triangles: vec![good, repeated, nan, collinear],
                },
                MeshGroup {
                    name: "b".into(),
                    triangles: vec![point, inf, sliver, good],
                },
                MeshGroup {
                    name: "c".into(),
                    triangles: vec![repeated],
                },
            ],
            ..Default::default()
        };
        let r = mesh.clean_triangles();
        assert_eq!(
            r,
            DegenerateReport {
                removed_degenerate: 5,
                removed_non_finite: 2
            }
        );
        assert_eq!(r.removed_total(), 7);
        assert_eq!(mesh.triangle_count(), 2);
        assert_eq!(mesh.groups.len(), 3, "emptied groups are kept");
        assert!(mesh.group("c").unwrap().triangles.is_empty());
        // Idempotent.
        assert_eq!(mesh.clean_triangles(), DegenerateReport::default());
    }

    #[test]
    fn degenerate_threshold_is_scale_free() {
        // The same small-but-valid triangle next to a large one is kept at any unit scale.
        for scale in [1e-3, 1.0, 1e3] {
            let s = |v: [f64; 3]| v.map(|c| c * scale);
            let mut mesh = ImportedMesh {
                groups: vec![MeshGroup {
                    name: "g".into(),
                    triangles: vec![
                        tri(s([0.0; 3]), s([10.0, 0.0, 0.0]), s([0.0, 10.0, 0.0])),
                        tri(s([0.0; 3]), s([1e-4, 0.0, 0.0]), s([0.0, 1e-4, 0.0])),
                        tri(s([0.0; 3]), s([1.0, 0.0, 0.0]), s([0.0, 1e-12, 0.0])),
                    ],
                }],
                ..Default::default()
            };
            let r = mesh.clean_triangles();
            assert_eq!(r.removed_degenerate, 1, "scale {scale}");
        }
    }

    #[test]
    fn data_uri_decoding() {
        assert_eq!(
            decode_data_uri("data:application/octet-stream;base64,AAEC/w==").unwrap(),
            vec![0, 1, 2, 255]
        );
        assert_eq!(
            decode_data_uri("data:application/gltf-buffer;base64,AAEC/w").unwrap(),
            vec![0, 1, 2, 255]
        );
        assert!(decode_data_uri("data:application/octet-stream,AAEC").is_err());
        assert!(decode_data_uri("data:image/png;base64,AAEC").is_err());
        assert!(decode_data_uri("data:application/octet-stream;base64,A$$C").is_err());
        assert!(decode_data_uri("data:application/octet-stream;base64").is_err());
    }

    #[test]
    fn percent_decoding() {
        assert_eq!(percent_decode("tree%20data.bin").unwrap(), "tree data.bin");
        assert_eq!(percent_decode("a/b.bin").unwrap(), "a/b.bin");
        assert!(percent_decode("bad%2").is_err());
        assert!(percent_decode("bad%zz.bin").is_err());
    }

    #[test]
    fn line_counter_reports_line_being_parsed() {
        use std::io::BufRead;
        let mut r = LineCounter::new(b"a\nb\nc");
        let mut lines = Vec::new();
        let mut buf = String::new();
        while r.read_line(&mut buf).unwrap() > 0 {
            lines.push((buf.trim_end().to_owned(), r.current_line()));
            buf.clear();
        }
        assert_eq!(
            lines,
            vec![("a".into(), 1), ("b".into(), 2), ("c".into(), 3)]
        );
    }

    fn obj_error(text: &str) -> MeshError {
        let dir = std::env::temp_dir();
        let path = dir.join(format!(
            "lumenscape_mesh_unit_{}_{}.obj",
            std::process::id(),
            text.len()
        ));
        // Parse from memory: the path is only used for messages and .mtl lookup.
        load_obj(&path, text.as_bytes()).unwrap_err()
    }

    #[test]
    fn obj_parse_errors_carry_the_line() {
        let e = obj_error("# c\nv 0 0 0\nv 1 x 0\nv 0 1 0\nf 1 2 3\n");
        assert!(matches!(e, MeshError::Parse { line: Some(3), .. }), "{e}");
        assert!(e.to_string().contains(":3:"), "{e}");
        let e = obj_error("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n");
        assert!(matches!(e, MeshError::Parse { line: Some(4), .. }), "{e}");
        let e = obj_error("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 -4\n");
        assert!(matches!(e, MeshError::Parse { line: Some(4), .. }), "{e}");
        let e = obj_error("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n");
        assert!(matches!(e, MeshError::Parse { line: Some(4), .. }), "{e}");
        let e = obj_error("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1/1 2/1 3/1\n");
        assert!(matches!(e, MeshError::Parse { line: Some(4), .. }), "{e}");
        let e = obj_error("v 0 0 0\nv 1 0 0\nv 0 1 0\nf\n");
        assert!(matches!(e, MeshError::Parse { line: Some(4), .. }), "{e}");
        let e = obj_error("v 0 0 0\r\nv 1 0 0\r\nv 0 1 0\r\nf 1/2/3/4 2 3\r\n");
        assert!(matches!(e, MeshError::Parse { line: Some(4), .. }), "{e}");
        let e = obj_error("v 0 0 0\nusemtl\nv 0 1 0\n");
        assert!(matches!(e, MeshError::Parse { line: Some(2), .. }), "{e}");
    }

    #[test]
    fn obj_groups_by_object_without_mtl_and_counts_skipped() {
        let text = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\n\
                    o first\nusemtl nowhere\nf 1 2 3\nl 1 2\np 1\nf 1 2\n\
                    o second\nf 2 4 3\nf 1 2 4 3\n";
        let path = std::env::temp_dir().join("lumenscape_mesh_unit_groups.obj");
        let mesh = load_obj(&path, text.as_bytes()).unwrap();
        let names: Vec<_> = mesh.groups.iter().map(|g| g.name.as_str()).collect();
        assert_eq!(names, ["first", "second"]);
        assert_eq!(mesh.group("first").unwrap().triangles.len(), 1);
        assert_eq!(mesh.group("second").unwrap().triangles.len(), 3);
        assert_eq!(mesh.skipped_non_triangle, 3);
        assert!(
            mesh.warnings.iter().any(|w| w.contains("nowhere")),
            "{:?}",
            mesh.warnings
        );
        assert!((mesh.total_area() - 2.0).abs() < 1e-15);
    }

    #[test]
    fn obj_without_faces_is_empty() {
        let path = std::env::temp_dir().join("lumenscape_mesh_unit_empty.obj");
        let e = load_obj(&path, b"v 0 0 0\nv 1 0 0\nl 1 2\n").unwrap_err();
        assert!(matches!(e, MeshError::Empty { .. }), "{e}");
        assert!(e.to_string().contains("1 non-triangle"), "{e}");
    }

    #[test]
    fn glb_header_checks() {
        let p = Path::new("x.glb");
        let mut h = b"glTF".to_vec();
        h.extend(2u32.to_le_bytes());
        h.extend(5u32.to_le_bytes()); // shorter than a header
        h.extend([0u8; 12]);
        assert!(matches!(
            load_gltf(p, &h, true),
            Err(MeshError::Parse { .. })
        ));
        h[8..12].copy_from_slice(&1000u32.to_le_bytes()); // longer than the file
        assert!(matches!(
            load_gltf(p, &h, true),
            Err(MeshError::Parse { .. })
        ));
        h[4..8].copy_from_slice(&1u32.to_le_bytes());
        assert!(
            load_gltf(p, &h, true)
                .unwrap_err()
                .to_string()
                .contains("version 1")
        );
        assert!(matches!(
            load_gltf(p, b"{\"asset\":{\"version\":\"2.0\"}}", true),
            Err(MeshError::Parse { .. })
        ));
    }
}
