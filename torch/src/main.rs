//! `dronewatt-torch`: the `dronewatt` command line with libtorch loaded, for training and
//! TorchScript models (`dronewatt` hands those commands here by itself). The command line
//! is `dronewatt`'s own source file, compiled in; nothing is duplicated.

#[allow(dead_code)]
#[path = "../../src/main.rs"]
mod cli;

fn main() -> std::process::ExitCode {
    dronewatt_torch::install();
    cli::main()
}
