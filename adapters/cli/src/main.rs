//! The `dash2sim` binary: the command line over `dash2sim-linux` ([`cli`] parses and
//! dispatches; each command's module renders what the library returns).

mod anchor;
mod cli;
mod decode;
mod demo;
mod export;
mod finish;
mod inspect;
mod map;
mod plot;
mod record;
mod render;
mod scenario;
mod signals;
mod verify;

fn main() -> std::process::ExitCode {
    cli::run()
}
