//! Atomic file writes: write a temporary file in the same folder, then rename it over the
//! target, so a product is either complete or absent.

use std::io::Write;
use std::path::Path;

/// Writes `bytes` to `path` atomically. Errors name the file.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), String> {
    let tmp = tmp_path(path);
    let res = (|| -> std::io::Result<()> {
        let mut f = std::fs::File::create(&tmp)?;
        f.write_all(bytes)?;
        f.sync_all()?;
        std::fs::rename(&tmp, path)
    })();
    res.map_err(|e| {
        let _ = std::fs::remove_file(&tmp);
        format!("{}: cannot write: {e}", path.display())
    })
}

/// Writes `path` atomically from a writer (buffered): for products too large to build in
/// memory first. Errors name the file; after an error nothing is left.
pub fn write_atomic_with(
    path: &Path,
    fill: impl FnOnce(&mut std::io::BufWriter<std::fs::File>) -> std::io::Result<()>,
) -> Result<(), String> {
    let tmp = tmp_path(path);
    let res = (|| -> std::io::Result<()> {
        let mut w = std::io::BufWriter::new(std::fs::File::create(&tmp)?);
        fill(&mut w)?;
        let f = w.into_inner().map_err(|e| e.into_error())?;
        f.sync_all()?;
        std::fs::rename(&tmp, path)
    })();
    res.map_err(|e| {
        let _ = std::fs::remove_file(&tmp);
        format!("{}: cannot write: {e}", path.display())
    })
}

/// The temporary name used for `path` (`.name.tmp-PID` in the same folder).
pub fn tmp_path(path: &Path) -> std::path::PathBuf {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    path.with_file_name(format!(".{name}.tmp-{}", std::process::id()))
}

/// An output folder written as a whole: the products go into a hidden staging folder beside
/// the target (`.NAME.partial-PID`, same parent, so the final rename is atomic), which
/// [`StagedDir::commit`] renames into place. A run that fails removes its staging folder (on
/// drop); a killed run leaves only the hidden `.partial` folder, never a complete-looking
/// product folder. The whole folder is replaced, so products of an earlier run are never mixed
/// with new ones: a folder holding an earlier run's products (`maket.json`, `summary.json` or
/// `lidar/` at its top) is replaced; any other non-empty folder is refused unless `replace` is
/// set (it may hold the user's own files).
#[derive(Debug)]
pub struct StagedDir {
    target: std::path::PathBuf,
    staging: std::path::PathBuf,
    committed: bool,
}

impl StagedDir {
    /// Checks the target and creates the staging folder (before any simulation work, so an
    /// unwritable or occupied `--out` is reported at once). `flag` names the option that
    /// allows replacing a non-empty folder (for the message).
    pub fn begin(target: &Path, replace: bool, flag: &str) -> Result<Self, String> {
        if target.exists() {
            if !target.is_dir() {
                return Err(format!(
                    "{}: exists and is not a folder (choose another --out)",
                    target.display()
                ));
            }
            let occupied = std::fs::read_dir(target)
                .map_err(|e| format!("{}: cannot read the folder: {e}", target.display()))?
                .next()
                .is_some();
            let earlier_run = ["maket.json", "summary.json", "lidar"]
                .iter()
                .any(|m| target.join(m).exists());
            if occupied && !earlier_run && !replace {
                return Err(format!(
                    "{}: the folder is not empty and holds no products of an earlier run; \
                     choose a new folder, or pass {flag} to replace its contents",
                    target.display()
                ));
            }
        }
        let name = target
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .filter(|n| !n.is_empty() && n != "." && n != "..")
            .ok_or_else(|| {
                format!(
                    "{}: name a folder to write into (not `.`, `..` or a root)",
                    target.display()
                )
            })?;
        let parent = match target.parent() {
            Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
            _ => std::path::PathBuf::from("."),
        };
        std::fs::create_dir_all(&parent)
            .map_err(|e| format!("{}: cannot create the folder: {e}", parent.display()))?;
        let staging = parent.join(format!(".{name}.partial-{}", std::process::id()));
        if staging.exists() {
            std::fs::remove_dir_all(&staging)
                .map_err(|e| format!("{}: cannot remove: {e}", staging.display()))?;
        }
        std::fs::create_dir(&staging).map_err(|e| {
            format!(
                "{}: cannot write into {}: {e}",
                target.display(),
                parent.display()
            )
        })?;
        Ok(Self {
            target: target.to_path_buf(),
            staging,
            committed: false,
        })
    }

    /// The folder the stages write into.
    pub fn path(&self) -> &Path {
        &self.staging
    }

    /// Moves the finished products into place (replacing the target's earlier contents).
    pub fn commit(mut self) -> Result<(), String> {
        let fail = |e: std::io::Error| {
            format!(
                "{}: cannot move the products into place: {e}",
                self.target.display()
            )
        };
        if self.target.exists() {
            let old = self.staging.with_file_name(
                self.staging
                    .file_name()
                    .unwrap()
                    .to_string_lossy()
                    .replace(".partial-", ".old-"),
            );
            std::fs::rename(&self.target, &old).map_err(fail)?;
            std::fs::rename(&self.staging, &self.target).map_err(fail)?;
            let _ = std::fs::remove_dir_all(&old);
        } else {
            std::fs::rename(&self.staging, &self.target).map_err(fail)?;
        }
        self.committed = true;
        Ok(())
    }
}

impl Drop for StagedDir {
    fn drop(&mut self) {
        if !self.committed {
            let _ = std::fs::remove_dir_all(&self.staging);
        }
    }
}
