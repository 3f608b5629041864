//! The floor for files a configuration names (imports nothing of ours): where a path
//! written in a file points ([`relative_to`]), and how a secret is read
//! ([`read_private`]). One of each, so every key of every config resolves and every secret
//! is guarded the same way.

use std::path::{Path, PathBuf};

/// `path` as written in the file `written_in`: an absolute path as it is, a relative one
/// against that file's folder (never the working directory, which changes with where
/// dronewatt was started). Used for every path a config or vehicle profile names.
pub fn relative_to(written_in: &Path, path: &Path) -> PathBuf {
    if path.is_absolute() {
        return path.to_path_buf();
    }
    written_in.parent().unwrap_or(Path::new("")).join(path)
}

/// [`relative_to`] in place, for an optional path field.
pub fn resolve(written_in: &Path, field: Option<&mut PathBuf>) {
    if let Some(p) = field {
        *p = relative_to(written_in, p);
    }
}

/// The bytes of a secret file (a signing key, a token, a password), refused on Unix
/// unless it is private to its owner: no read, write or execute bit for group or others.
/// The error names the file and its mode, and says how to fix it; the caller adds the key.
pub fn read_private(path: &Path) -> Result<Vec<u8>, String> {
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        let mode = std::fs::metadata(path)
            .map_err(|e| format!("cannot read {}: {e}", path.display()))?
            .permissions()
            .mode();
        if mode & 0o077 != 0 {
            return Err(format!(
                "{} is accessible to group or others (mode {:03o}); make it private: chmod 600 {}",
                path.display(),
                mode & 0o777,
                path.display()
            ));
        }
    }
    std::fs::read(path).map_err(|e| format!("cannot read {}: {e}", path.display()))
}

/// [`read_private`] as UTF-8 text.
pub fn read_private_text(path: &Path) -> Result<String, String> {
    String::from_utf8(read_private(path)?)
        .map_err(|_| format!("{}: not UTF-8 text", path.display()))
}

#[cfg(test)]
mod tests;
