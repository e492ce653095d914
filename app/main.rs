//! The `meshvox` binary. Natively it is the command-line tool (and, later, the desktop viewer); the wasm32 entry
//! point for the web page arrives with the web demo.

#[cfg(not(target_arch = "wasm32"))]
mod cli;

#[cfg(not(target_arch = "wasm32"))]
fn main() -> std::process::ExitCode {
    cli::main()
}

#[cfg(target_arch = "wasm32")]
fn main() {}
