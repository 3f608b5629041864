//! Bakes libtorch's location into every binary and test as an rpath, so nothing needs
//! LD_LIBRARY_PATH. `LIBTORCH` comes from `.cargo/config.toml` (the project-local venv
//! that `scripts/setup-libtorch.sh` makes).
fn main() {
    println!("cargo:rerun-if-env-changed=LIBTORCH");
    if let Ok(dir) = std::env::var("LIBTORCH") {
        let lib = std::path::Path::new(&dir).join("lib");
        let lib = lib.canonicalize().unwrap_or(lib);
        println!("cargo:rustc-link-arg=-Wl,-rpath,{}", lib.display());
    }
}
