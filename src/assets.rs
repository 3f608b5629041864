//! What dronewatt ships, found the same way wherever it runs from: the one resolver.
//!
//! Every shipped file is compiled into the binary, so a binary copied anywhere (`cargo
//! install`, `/usr/local/bin/dronewatt`) gives the same figures as the checkout's, from any
//! working directory. Nothing here ever looks in the current directory.
//!
//! | asset | compiled in | on disk (first hit wins) |
//! |---|---|---|
//! | vehicle profiles (`m100`, `x500`, …) | [`crate::model::profile::BUILT_IN`] | — (a file named on the command line or in the config) |
//! | the M100's calibrated profile | [`M100_CALIBRATED_TOML`] | — (`--calibrated FILE`, `[forecast.live] calibrated_profile`) |
//! | the plot's font | [`FONT`] | — |
//! | the dashboard's page | the web sink's `index.html` (`include_str!`) | — |
//! | the LSTM (card, weights, trees) | [`DEFAULT_MODEL`], [`PAPER_MODEL`] | [`model_dir`]: beside the binary, else the compiled-in copy written once to the cache |
//!
//! A model is a folder of files that the loaders (the CPU kernel, the libtorch helper)
//! read by path, so the compiled-in copy is written once to
//! `$XDG_CACHE_HOME/dronewatt/assets-<hash>/` (else the temporary directory), named by a
//! hash of its contents: a newer binary never reads an older copy. A model folder beside the
//! binary wins over the compiled-in copy: `config/models/…` in the folder of the executable
//! or up to three folders above it (a checkout's `target/{debug,release}`, `target/*/deps`),
//! or `share/dronewatt/config/models/…` beside an installed `bin/`; that is where a model
//! retrained in a checkout is found without a rebuild.

use std::path::{Path, PathBuf};

use anyhow::Context;
use sha2::{Digest, Sha256};

/// The M100 with the physics models fitted by `dronewatt-lab calibrate` (its `<model>_cal`
/// models are the M100 forecast's members).
pub const M100_CALIBRATED_TOML: &str = include_str!("../config/vehicles/m100-calibrated.toml");

/// DejaVu Sans (free licence, `config/fonts/DejaVuSans.LICENSE`): the plots' text.
pub static FONT: &[u8] = include_bytes!("../config/fonts/DejaVuSans.ttf");

/// A model folder compiled in: its path under the checkout and its files (name, bytes).
pub struct EmbeddedModel {
    /// The folder relative to a checkout or install root, e.g. `config/models/lstm-m100`.
    pub rel: &'static str,
    /// Every file the card names (a unit test checks it against the card), and the card.
    pub files: &'static [(&'static str, &'static [u8])],
}

/// The default LSTM ensemble and its trees ([`crate::model::lstm::DEFAULT_MODEL_DIR`]).
pub static DEFAULT_MODEL: EmbeddedModel = EmbeddedModel {
    rel: "config/models/lstm-m100",
    files: &[
        (
            "card.toml",
            include_bytes!("../config/models/lstm-m100/card.toml"),
        ),
        (
            "member-7.safetensors",
            include_bytes!("../config/models/lstm-m100/member-7.safetensors"),
        ),
        (
            "member-11.safetensors",
            include_bytes!("../config/models/lstm-m100/member-11.safetensors"),
        ),
        (
            "member-13.safetensors",
            include_bytes!("../config/models/lstm-m100/member-13.safetensors"),
        ),
        (
            "trees.txt",
            include_bytes!("../config/models/lstm-m100/trees.txt"),
        ),
    ],
};

/// The paper's single network, what `learn --fine-tune` starts from
/// ([`crate::model::lstm::PAPER_MODEL_DIR`]).
pub static PAPER_MODEL: EmbeddedModel = EmbeddedModel {
    rel: "config/models/lstm-m100-h128",
    files: &[
        (
            "card.toml",
            include_bytes!("../config/models/lstm-m100-h128/card.toml"),
        ),
        (
            "model.safetensors",
            include_bytes!("../config/models/lstm-m100-h128/model.safetensors"),
        ),
    ],
};

/// The models compiled in.
pub static EMBEDDED_MODELS: [&EmbeddedModel; 2] = [&DEFAULT_MODEL, &PAPER_MODEL];

/// The folders beside the executable where shipped files may lie, nearest first.
fn roots_beside_exe() -> Vec<PathBuf> {
    let Ok(exe) = std::env::current_exe() else {
        return Vec::new();
    };
    let mut roots = Vec::new();
    for dir in exe.ancestors().skip(1).take(4) {
        roots.push(dir.to_path_buf());
    }
    if let Some(prefix) = exe.parent().and_then(Path::parent) {
        roots.push(prefix.join("share/dronewatt"));
    }
    roots
}

/// The shipped model folder `rel` (e.g. [`crate::model::lstm::DEFAULT_MODEL_DIR`]) holding a
/// `card.toml`: beside the binary, else the compiled-in copy (written to the cache once).
/// `None` only for a folder not shipped, or when no compiled-in copy could be written (a
/// warning says where it tried).
pub fn model_dir(rel: &str) -> Option<PathBuf> {
    if let Some(found) = roots_beside_exe()
        .into_iter()
        .map(|r| r.join(rel))
        .find(|c| c.join("card.toml").is_file())
    {
        return Some(found);
    }
    let model = EMBEDDED_MODELS.iter().find(|m| m.rel == rel)?;
    match extract(model, &cache_root()) {
        Ok(dir) => Some(dir),
        Err(e) => {
            tracing::warn!("{rel}: the compiled-in model could not be written out: {e:#}");
            None
        }
    }
}

/// Where compiled-in files are written: the user's cache, else the temporary directory.
fn cache_root() -> PathBuf {
    dirs::cache_dir()
        .unwrap_or_else(std::env::temp_dir)
        .join("dronewatt")
}

/// A hash of a model's files (names and bytes), to name its folder in the cache.
fn content_hash(model: &EmbeddedModel) -> String {
    let mut h = Sha256::new();
    for (name, bytes) in model.files {
        h.update(name.as_bytes());
        h.update((bytes.len() as u64).to_le_bytes());
        h.update(bytes);
    }
    h.finalize()[..8]
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect()
}

/// Write `model` under `root` (once: a complete copy is reused) and return its folder. The
/// files go to a fresh folder first, renamed into place whole, so that a run that stops
/// half-way, or two runs at once, never leave a partial model where one is read.
pub fn extract(model: &EmbeddedModel, root: &Path) -> anyhow::Result<PathBuf> {
    let base = root.join(format!("assets-{}", content_hash(model)));
    let dir = base.join(model.rel);
    if complete(model, &dir) {
        return Ok(dir);
    }
    let staging = root.join(format!(
        "staging-{}-{}",
        std::process::id(),
        content_hash(model)
    ));
    let staged = staging.join(model.rel);
    std::fs::create_dir_all(&staged)
        .with_context(|| format!("{}: cannot create", staged.display()))?;
    for (name, bytes) in model.files {
        let p = staged.join(name);
        std::fs::write(&p, bytes).with_context(|| format!("{}: cannot write", p.display()))?;
    }
    if let Some(parent) = dir.parent() {
        std::fs::create_dir_all(parent)
            .with_context(|| format!("{}: cannot create", parent.display()))?;
    }
    // Another run may have put its copy in place meanwhile: then ours is dropped.
    if std::fs::rename(&staged, &dir).is_err() && !complete(model, &dir) {
        let _ = std::fs::remove_dir_all(&staging);
        anyhow::bail!("{}: cannot move the model into place", dir.display());
    }
    let _ = std::fs::remove_dir_all(&staging);
    tracing::debug!("{}: the compiled-in model, written out", dir.display());
    Ok(dir)
}

/// Whether `dir` holds every file of `model` with its exact length.
fn complete(model: &EmbeddedModel, dir: &Path) -> bool {
    model.files.iter().all(|(name, bytes)| {
        std::fs::metadata(dir.join(name)).is_ok_and(|m| m.len() == bytes.len() as u64)
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::card::ModelCard;

    /// Each compiled-in model holds every file its card names, so the written-out copy loads.
    #[test]
    fn compiled_in_models_hold_what_their_cards_name() {
        let tmp = tempfile::tempdir().unwrap();
        for m in EMBEDDED_MODELS {
            let dir = extract(m, tmp.path()).unwrap();
            let card = ModelCard::load(&dir.join("card.toml")).unwrap();
            let mut named = vec![card.weights.clone()];
            named.extend(card.members.iter().cloned());
            if let Some(t) = &card.trees {
                named.push(t.file.clone());
            }
            for n in named {
                assert!(
                    m.files.iter().any(|(f, _)| *f == n),
                    "{}: the card names {n}, not compiled in",
                    m.rel
                );
            }
            // the copy is byte-identical to the checkout's
            for (name, bytes) in m.files {
                let shipped = Path::new(env!("CARGO_MANIFEST_DIR")).join(m.rel).join(name);
                assert_eq!(std::fs::read(&shipped).unwrap(), *bytes, "{}", name);
            }
            // a second call reuses the copy
            assert_eq!(extract(m, tmp.path()).unwrap(), dir);
        }
    }

    /// The compiled-in calibrated profile parses and is calibrated.
    #[test]
    fn the_m100_calibrated_profile_is_compiled_in() {
        let p = crate::model::profile::m100_calibrated().unwrap();
        assert!(p.calibration.is_some());
        assert!(crate::model::profile::calibrated_profile(Some(Path::new(
            "/nonexistent/cal.toml"
        )))
        .is_err());
    }
}
