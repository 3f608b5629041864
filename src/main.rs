//! `dronewatt`: the command line ([`dronewatt::cli`]), without libtorch.

fn main() -> std::process::ExitCode {
    dronewatt::cli::main()
}
