//! Files drawn by writers that insist on a path of their own (plotters' backends), written
//! like every other file of the project: to a temporary file beside the target, renamed
//! into place once complete, so that a failure never leaves a truncated picture.

use std::path::Path;

/// Calls `write` with a temporary path in `path`'s folder (with `path`'s extension, which
/// the writer may read the format from), then renames it to `path`. On an error the
/// temporary file is removed and `path` is left as it was.
pub fn write_via_temp(
    path: &Path,
    write: impl FnOnce(&Path) -> Result<(), String>,
) -> Result<(), String> {
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    let suffix = path
        .extension()
        .map(|e| format!(".{}", e.to_string_lossy()))
        .unwrap_or_default();
    let mut builder = tempfile::Builder::new();
    builder.prefix(".point-springs-").suffix(&suffix);
    // Readable like a file `File::create` makes (the umask still applies), not 0600.
    #[cfg(unix)]
    builder.permissions(std::os::unix::fs::PermissionsExt::from_mode(0o644));
    let temp = builder
        .tempfile_in(dir)
        .map_err(|e| format!("{}: {e}", path.display()))?;
    write(temp.path())?;
    temp.persist(path)
        .map_err(|e| format!("{}: {}", path.display(), e.error))?;
    Ok(())
}
