//! The `zeroset` binary: the library's CLI with the built-in primitives.

fn main() -> std::process::ExitCode {
    zeroset::cli::main()
}
