//! A `zeroset` binary that also knows this crate's primitive types: register them, then run the
//! library's command line.

fn main() -> std::process::ExitCode {
    zeroset_custom_primitives::register_all();
    zeroset::cli::main()
}
