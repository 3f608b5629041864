//! `dronewatt`: the command line ([`dronewatt::cli`]), without libtorch.

/// mimalloc, not glibc's malloc: a large fleet allocates and frees small buffers at a
/// high rate from several threads (see Cargo.toml).
#[global_allocator]
static ALLOC: mimalloc::MiMalloc = mimalloc::MiMalloc;

fn main() -> std::process::ExitCode {
    dronewatt::cli::main()
}
