//! `nephele` command-line program: [`nephele::cli::main`] with the process's arguments. All the
//! work, the command line's included, lives in the library (so the Python wheel's `nephele`
//! command runs the same code).

fn main() -> std::process::ExitCode {
    std::process::ExitCode::from(nephele::cli::main(std::env::args_os()))
}
