//! `dronewatt-torch`: the `dronewatt` command line ([`dronewatt::cli`]) with libtorch loaded,
//! for training and TorchScript models (`dronewatt` hands those commands here by itself).

fn main() -> std::process::ExitCode {
    dronewatt_torch::install();
    dronewatt_lab::cli::torch_main()
}
