//! `harvemu`: the command line of the emulated 4MZ-6A cotton harvester.
//!
//! Exit codes (docs/PROMISES.md): 0 success, 1 an expectation failed, 2 bad input or usage,
//! 3 an output could not be created or written, 4 a node crashed beyond its restart policy,
//! 70 harvemu itself failed, 130 / 143 / 129 stopped by SIGINT / SIGTERM / SIGHUP.

use clap::{Parser, Subcommand};
use std::process::ExitCode;
use supervisor::exit::{self, Ended};
use supervisor::{
    bench, campaign, configs, convert, coverage, dbc, import, inspect, replay, run, scenarios_cli, soak, stop,
};

#[derive(Parser)]
#[command(
    name = "harvemu",
    version,
    about = "Emulator of a cotton harvester's CAN network",
    after_help = EXIT_CODES
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

const EXIT_CODES: &str = "\
Exit codes:
  0    success
  1    an expectation of a scenario or soak failed
  2    bad input or usage
  3    an output (trace, report, JUnit XML, DBC, exported config) could not be created or written
  4    a node crashed more often than its restart policy allows
  70   harvemu itself failed (a bug: please report it)
  130  stopped by SIGINT (Ctrl-C), 143 by SIGTERM, 129 by SIGHUP (outputs are finished)";

// One example or more per subcommand, under its --help.
const RUN_EXAMPLES: &str = "\
Examples:
  harvemu run                                        the default harvester, real time (Ctrl-C stops)
  harvemu run --fast --for 10m --record harvest.log  10 minutes of virtual time, as fast as possible
  harvemu config export mine                         the built-in harvester, to edit
  harvemu run mine/harvester.ron --seed 7 --for 120s your copy, another seed, two minutes";

const REPLAY_EXAMPLES: &str = "\
Examples:
  harvemu replay harvest.asc --without D3 --skip-emulated --fast";

const CONVERT_EXAMPLES: &str = "\
Examples:
  harvemu convert harvest.log harvest.blf          candump log to BLF (CANoe, CANalyzer, python-can)
  harvemu convert harvest.blf harvest.pcapng       BLF to pcapng (Wireshark)
  harvemu convert harvest.pcapng harvest.mf4       to MF4 (asammdf, CANape)
  harvemu convert capture.pcap harvest.log         a tcpdump capture to a candump log";

const SCENARIO_EXAMPLES: &str = "\
Examples:
  harvemu scenario bus_off                           a built-in scenario, by its name
  harvemu scenario conformance                       every scenario of a folder (here the built-in one)
  harvemu scenario 'configs/scenarios/*.ron' --junit report.xml   quoted: harvemu expands it
  harvemu scenario configs/scenarios/bus_off.ron --seed 7 --report bus_off.html";

const CAMPAIGN_EXAMPLES: &str = "\
Examples:
  harvemu campaign harvest --runs 200 --out campaign       the built-in campaign, on every core
  harvemu campaign harvest --runs 1000 --seed 7 --shard 2/4 --out shard-2
  harvemu campaign merge shard-1 shard-2 shard-3 shard-4 --out campaign
  harvemu scenario campaign/failing/run-17.ron             rerun a shrunk failing run";

const SOAK_EXAMPLES: &str = "\
Examples:
  harvemu soak --hours 1 --seed 7";

const VALIDATE_EXAMPLES: &str = "\
Examples:
  harvemu validate configs/harvester.ron 'configs/nodes/*.ron' 'configs/scenarios/*.ron'
  harvemu validate configs/scenarios                 a folder: every .ron file directly in it";

const INSPECT_EXAMPLES: &str = "\
Examples:
  harvemu inspect 0300A0F5#0101 --json";

const BENCH_EXAMPLES: &str = "\
Examples:
  harvemu bench --only harvester --json";

const COVERAGE_EXAMPLES: &str = "\
Examples:
  harvemu scenario c0_bus_off --coverage cov/c0
  harvemu coverage merge cov/c0 cov/campaign --out cov/all
  genhtml cov/all/c0_alarm.info --branch-coverage -o cov/html";
const DBC_EXAMPLES: &str = "\
Examples:
  harvemu dbc -o harvester.dbc";

const IMPORT_EXAMPLES: &str = "\
Examples:
  harvemu import tractor.dbc --out tractor                 a network from a DBC; then:
  harvemu run tractor/network.ron --fast --for 60s --record tractor.log
  harvemu import tractor.dbc --out tractor --signals walk --force   signals that move
  harvemu dbc --config tractor/network.ron -o again.dbc    and back to a DBC";

const CONFIG_EXAMPLES: &str = "\
Examples:
  harvemu config export configs        the built-in configs, to edit: ./configs/ then wins
  harvemu config export my-configs     then: harvemu run my-configs/harvester.ron
  harvemu config list";

const PROTOCOL_EXAMPLES: &str = "\
Examples:
  harvemu protocol --markdown";

#[derive(Subcommand)]
enum Command {
    /// Run the emulated harvester on the virtual hub.
    #[command(after_help = RUN_EXAMPLES)]
    Run(run::Args),
    /// Play a trace (candump log, ASC, BLF, pcapng, MF4) onto the emulated harvester's bus.
    #[command(after_help = REPLAY_EXAMPLES)]
    Replay(replay::Args),
    /// Run scenarios in virtual time and give verdicts (exit code 1 if any expectation fails,
    /// the others as `harvemu --help` lists them).
    #[command(after_help = SCENARIO_EXAMPLES)]
    Scenario(scenarios_cli::ScenarioArgs),
    /// Many runs of a scenario with random faults, each failing run shrunk to a small scenario
    /// (exit code 1 if any run failed); `merge` joins the shards of a campaign.
    #[command(after_help = CAMPAIGN_EXAMPLES)]
    Campaign(campaign::cli::Args),
    /// A long run with random faults (default: 24 h virtual): memory over time and the books.
    #[command(after_help = SOAK_EXAMPLES)]
    Soak(soak::Args),
    /// Check harvester configs, node scripts and scenarios without running anything.
    #[command(after_help = VALIDATE_EXAMPLES)]
    Validate(scenarios_cli::ValidateArgs),
    /// Convert a trace from one format to another (candump log, ASC, BLF, pcapng, MF4), saying
    /// what the target cannot carry.
    #[command(after_help = CONVERT_EXAMPLES)]
    Convert(convert::Args),
    /// Decode one frame: identifier fields, catalogue message, CRC, bit lengths, filters.
    #[command(after_help = INSPECT_EXAMPLES)]
    Inspect(inspect::Args),
    /// Measure how fast the emulator runs (saturated bus; many buses in one process).
    #[command(after_help = BENCH_EXAMPLES)]
    Bench(bench::Args),
    /// Firmware code coverage: merge the coverage folders of several runs.
    #[command(subcommand, after_help = COVERAGE_EXAMPLES)]
    Coverage(coverage::Args),
    /// Write a DBC of the whole harvester (catalogue messages, cycle times from the node scripts),
    /// or of a network imported from a DBC (its database, the scripts' cycle times).
    #[command(after_help = DBC_EXAMPLES)]
    Dbc(dbc::Args),
    /// Write a runnable network from a DBC file: a network file and a node script per node.
    #[command(after_help = IMPORT_EXAMPLES)]
    Import(import::Args),
    /// The built-in configs (harvester, node scripts, scenarios, soak): write them out to edit,
    /// or list them.
    #[command(subcommand, after_help = CONFIG_EXAMPLES)]
    Config(configs::cli::Command),
    /// Print the message catalogue (`--markdown`: the generated part of docs/PROTOCOL.md).
    #[command(after_help = PROTOCOL_EXAMPLES)]
    Protocol {
        /// Print the Markdown tables of docs/PROTOCOL.md.
        #[arg(long)]
        markdown: bool,
    },
}

fn main() -> ExitCode {
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        Err(e) => {
            // clap prints its own help and errors; its exit code for bad usage is 2. Help or a
            // version that does not reach its output is an output that failed.
            let code = if e.use_stderr() { exit::BAD_INPUT } else { exit::OK };
            let printed = e
                .print()
                .and_then(|()| std::io::Write::flush(&mut std::io::stdout()));
            return ExitCode::from(if printed.is_err() {
                exit::OUTPUT_FAILED
            } else {
                code
            });
        }
    };
    // RUST_LOG controls diagnostics (default: warnings); they go to stderr, never into traces.
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env().unwrap_or_else(|_| "warn".into()),
        )
        .with_writer(supervisor::say::Log)
        // Colours only for a terminal: a log file or a CI job's output gets plain text.
        .with_ansi(std::io::IsTerminal::is_terminal(&std::io::stderr()))
        .init();
    // Before anything else: a signal from here on stops a run in order, not the process; the
    // quick commands (and bench, which has no outputs to finish) keep the default.
    let runs = matches!(
        cli.command,
        Command::Run(_)
            | Command::Replay(_)
            | Command::Scenario(_)
            | Command::Campaign(_)
            | Command::Soak(_)
            | Command::Convert(_)
    );
    let handled = stop::ignore_file_size_limit().and_then(|()| if runs { stop::install() } else { Ok(()) });
    if let Err(e) = handled {
        // The system refused: not the input's fault, nor an output's.
        supervisor::say!("harvemu: error: cannot handle signals: {e}");
        return ExitCode::from(exit::INTERNAL);
    }
    let done = Ended::default();
    let result = match cli.command {
        Command::Run(args) => run::run(&args),
        Command::Replay(args) => replay::run(&args),
        Command::Validate(args) => scenarios_cli::validate(&args).map(|()| done),
        Command::Scenario(args) => scenarios_cli::run(&args),
        Command::Campaign(args) => campaign::cli::run(&args),
        Command::Soak(args) => soak::run(&args),
        Command::Convert(args) => convert::run(&args),
        Command::Inspect(args) => inspect::run(&args).map(|()| done),
        Command::Bench(args) => bench::run(&args).map(|()| done),
        Command::Dbc(args) => dbc::run(&args).map(|()| done),
        Command::Import(args) => import::run(&args).map(|()| done),
        Command::Coverage(args) => coverage::run(&args).map(|()| done),
        Command::Config(command) => configs::cli::run(&command).map(|()| done),
        Command::Protocol { markdown } => protocol(markdown).map(|()| done),
    };
    if let Err(e) = &result {
        supervisor::say!("harvemu: error: {}", e.report());
    }
    let code = exit::code(&result, stop::received());
    // A message standard error did not take is an output that failed; any other failure's code
    // says more.
    ExitCode::from(if code == exit::OK && supervisor::say::failed() {
        exit::OUTPUT_FAILED
    } else {
        code
    })
}

/// `harvemu protocol`: the catalogue on standard output.
fn protocol(markdown: bool) -> supervisor::Result<()> {
    let text = if markdown {
        format!("{}\n", protocol::catalogue::doc::markdown())
    } else {
        protocol::catalogue::MESSAGES
            .iter()
            .map(|m| format!("{:02X} {:<24} {}\n", m.number, m.name, m.doc))
            .collect()
    };
    supervisor::output::stdout(&text)
}
