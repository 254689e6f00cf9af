//! The `trayecto` binary: the front ends (the command line in [`cli`], the web UI in [`server`])
//! on top of the library's render pipeline (`trayecto::pipeline`).

mod cli;
mod server;

fn main() -> std::process::ExitCode {
    cli::main()
}
