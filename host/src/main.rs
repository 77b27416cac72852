use clap::Parser;

fn main() -> std::process::ExitCode {
    let cli = gridrt::cli::Cli::parse();
    match gridrt::cli::run(cli) {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            std::process::ExitCode::FAILURE
        }
    }
}
