//! The `dash2sim` binary: argument parsing lives in [`dash2sim_linux::cli`].
fn main() -> std::process::ExitCode {
    // Output piped into `head` ends the process quietly, as for any Unix tool, instead of a
    // panic in `println!` (Rust ignores SIGPIPE by default). Logs are closed before any
    // command prints, so nothing is lost.
    sigpipe::reset();
    dash2sim_linux::cli::run()
}
