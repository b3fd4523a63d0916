use clap::Parser;
use vwb_app::cli::{Cli, Command, run_info, run_render};

fn main() {
    env_logger::Builder::from_env(env_logger::Env::default().default_filter_or("warn")).init();
    let cli = Cli::parse();
    let result = match &cli.command {
        Some(Command::Render(a)) => run_render(cli.preset.as_deref(), a),
        Some(Command::Info) => run_info(),
        None => vwb_app::window::run(&cli),
    };
    if let Err(e) = result {
        eprintln!("error: {e:#}");
        std::process::exit(1);
    }
}
