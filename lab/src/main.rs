//! `dronewatt-lab`: the research commands ([`dronewatt_lab::cli`]), without libtorch.

fn main() -> std::process::ExitCode {
    dronewatt_lab::cli::main()
}
