use clap::Parser;
use vwb_app::cli::{
    Cli, Command, run_bench, run_compare, run_experiment, run_info, run_render, run_scene,
    run_suggest_tf, run_sweep,
};

fn main() {
    env_logger::Builder::from_env(env_logger::Env::default().default_filter_or("warn")).init();
    let cli = Cli::parse();
    vwb_app::cli::install_user_plugins(&cli);
    let result = match &cli.command {
        Some(Command::Render(a)) => run_render(cli.preset.as_deref(), a),
        Some(Command::Compare(a)) => run_compare(cli.preset.as_deref(), a),
        Some(Command::Bench(a)) => run_bench(cli.preset.as_deref(), a),
        Some(Command::Sweep(a)) => run_sweep(cli.preset.as_deref(), a),
        Some(Command::Scene(a)) => run_scene(cli.preset.as_deref(), a),
        Some(Command::Crop(a)) => vwb_app::crop::run_crop(cli.preset.as_deref(), a),
        Some(Command::SuggestTf(a)) => run_suggest_tf(a),
        Some(Command::Run(a)) => run_experiment(a),
        Some(Command::Evolve(a)) => vwb_app::cli::run_evolve(cli.preset.as_deref(), a),
        Some(Command::AdaptTf(a)) => vwb_app::cli::run_adapt_tf(a),
        Some(Command::Gallery(a)) => vwb_app::cli::run_gallery(cli.preset.as_deref(), a),
        Some(Command::Info(a)) => run_info(a),
        Some(Command::Data(a)) => vwb_app::data_cmd::run(a),
        None => vwb_app::window::run(&cli),
    };
    if let Err(e) = result {
        eprintln!("error: {e:#}");
        std::process::exit(1);
    }
}
