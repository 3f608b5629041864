//! `learn` refuses the same log given twice: two copies of one flight would sit on both
//! sides of the held-out split (a 0.0 % error that means nothing) or count twice in the fit.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use sha2::{Digest, Sha256};

/// The SHA-256 of a file's content, read in chunks.
fn content_hash(p: &Path) -> Result<[u8; 32]> {
    let mut f = std::fs::File::open(p).with_context(|| format!("{}: cannot open", p.display()))?;
    let mut h = Sha256::new();
    std::io::copy(&mut f, &mut h).with_context(|| format!("{}: cannot read", p.display()))?;
    Ok(h.finalize().into())
}

/// An error naming both files when two of `logs` have the same content (whatever their
/// names; the same path named twice too). Empty files are left to the readers (each is
/// refused there as holding no log).
pub fn refuse_duplicates(logs: &[PathBuf]) -> Result<()> {
    let mut seen: Vec<([u8; 32], &PathBuf)> = Vec::with_capacity(logs.len());
    for p in logs {
        if std::fs::metadata(p).is_ok_and(|m| m.len() == 0) {
            continue;
        }
        let h = content_hash(p)?;
        if let Some((_, first)) = seen.iter().find(|(s, _)| *s == h) {
            let short: String = h[..6].iter().map(|b| format!("{b:02x}")).collect();
            anyhow::bail!(
                "{} and {} are the same log (content SHA-256 {short}…): give each flight once; a copy would be scored against itself",
                first.display(),
                p.display()
            );
        }
        seen.push((h, p));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn two_copies_are_refused_naming_both() {
        let dir = tempfile::tempdir().unwrap();
        let (a, b, c) = (
            dir.path().join("a.tlog"),
            dir.path().join("copy-of-a.tlog"),
            dir.path().join("c.tlog"),
        );
        std::fs::write(&a, b"one flight").unwrap();
        std::fs::write(&b, b"one flight").unwrap();
        std::fs::write(&c, b"another flight").unwrap();
        refuse_duplicates(&[a.clone(), c.clone()]).unwrap();
        let e = refuse_duplicates(&[a, c, b]).unwrap_err().to_string();
        assert!(
            e.contains("a.tlog and") && e.contains("copy-of-a.tlog"),
            "{e}"
        );
    }
}
