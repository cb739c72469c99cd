//! `echoloc-lab`: the std command-line tool beside the firmware library, a
//! thin shell over the `echoloc_lab` library. Units on the command line and
//! in files are metres and degrees (DESIGN §7); output is JSON.

use std::process::ExitCode;

use clap::{Parser, Subcommand};
use echoloc_lab::{bag, bench, board, credence, link, map, predict, replay, scenario, simulate_cmd, LabError};

#[derive(Parser)]
#[command(name = "echoloc-lab", version, about = "echoloc's lab tool: maps, windows, prediction, credence")]
struct Cli {
    #[command(subcommand)]
    cmd: Cmd,
}

#[derive(Subcommand)]
enum Cmd {
    /// Polygon maps: import to the firmware's blob, inspect.
    #[command(subcommand)]
    Map(map::MapCmd),
    /// The pseudo-path layout of a sensor window, eq. (1)-(6).
    Window(predict::WindowArgs),
    /// Predicted readings: one JSON object per transducer per line.
    Predict(predict::PredictArgs),
    /// Credence data: run the physical sonar model as the paper's experiment, one CSV per day.
    Synth(credence::SynthArgs),
    /// Self-referencing in a simulated world (a route, odometry, a physical sonar), or on a lidar run's real geometry (--from-scans): verdicts, threshold method and EKF.
    Simulate(Box<simulate_cmd::SimulateArgs>),
    /// A robot's log (CSV, docs/log.md) or ROS 2 bag (docs/bags.md) through prediction, verdicts, the threshold method and the EKF.
    Replay(Box<replay::ReplayArgs>),
    /// Logs: a ROS 2 bag written as the plain CSV log, or a log as a ROS 2 bag (docs/log.md, docs/bags.md).
    Log(bag::cli::LogArgs),
    /// Scenario files: replay one on the host through the same filters, or convert a robot's log into one.
    Scenario(scenario::ScenarioArgs),
    /// A log or bag on the emulated board (QEMU) end to end, its figures beside the host's.
    Board(board::BoardArgs),
    /// Benchmarks: echoloc against ray fans on grids and polygons, per window, with completeness and memory.
    Bench(bench::BenchArgs),
    /// The host link: stream odometry to a controller (the QEMU firmware, or a socket) and print what it sends back as JSON lines.
    Link(link::LinkArgs),
    /// Credence net: leave-one-day-out evaluation against the Gaussian baseline, training, quantisation, figures.
    Train(credence::TrainArgs),
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    // Splitting a large polygon needs a few MB of stack (fixed-capacity
    // working sets, as on the firmware side), and every command that reads a
    // map source may split one (`map import`, `predict --map x.yaml`): run
    // them all on a thread that has it.
    let result = std::thread::Builder::new()
        .stack_size(256 << 20)
        .spawn(move || run(cli.cmd))
        .map_err(|e| LabError(format!("cannot start the worker thread: {e}")))
        .and_then(|h| h.join().unwrap_or_else(|_| Err(LabError("internal error: the worker panicked".into()))));
    match result {
        Ok(json) => {
            use std::io::Write;
            match writeln!(std::io::stdout().lock(), "{json}") {
                Ok(()) => ExitCode::SUCCESS,
                // A reader that stopped early (`| head`) is not our failure.
                Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => ExitCode::SUCCESS,
                Err(e) => {
                    eprintln!("echoloc-lab: cannot write the output: {e}");
                    ExitCode::FAILURE
                }
            }
        }
        Err(e) => {
            eprintln!("echoloc-lab: {e}");
            ExitCode::FAILURE
        }
    }
}

fn run(cmd: Cmd) -> Result<String, LabError> {
    match cmd {
        Cmd::Map(c) => map::run(c),
        Cmd::Window(a) => predict::window_cmd(&a),
        Cmd::Predict(a) => predict::predict_cmd(&a),
        Cmd::Synth(a) => credence::synth_cmd(&a).map_err(|e| LabError(e.to_string())),
        Cmd::Simulate(a) => simulate_cmd::simulate_cmd(&a),
        Cmd::Replay(a) => replay::replay_cmd(&a),
        Cmd::Log(a) => bag::cli::log_cmd(&a),
        Cmd::Scenario(a) => scenario::run(a),
        Cmd::Link(a) => link::link_cmd(&a),
        Cmd::Bench(a) => bench::bench_cmd(&a),
        Cmd::Board(a) => board::board_cmd(&a),
        Cmd::Train(a) => credence::train_cmd(&a).map_err(|e| LabError(e.to_string())),
    }
}
