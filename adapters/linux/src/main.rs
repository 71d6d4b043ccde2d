//! The `dash2sim` binary: argument parsing lives in [`dash2sim_linux::cli`].
fn main() -> std::process::ExitCode {
    dash2sim_linux::cli::run()
}
