//! The harvester config file (`configs/harvester.ron`): reading it, the node files it names,
//! and the checks that refuse a config whose nodes would be mistaken for one another.

use crate::configs::Source;
pub use crate::network::{NetworkConfig, RestartPolicy};
use bus::bits::BitRate;
use bus::engine::NodeId;
use bus::time::BusTime;
use nodes::firmware::FirmwareSpec;
use nodes::monitor::MonitorConfig;
use nodes::plant::PlantConfig;
use nodes::script::NodeScript;
use nodes::{Error, Problem};
use protocol::ident::Address;
use serde::Deserialize;
use std::path::Path;
use std::sync::Arc;

/// A harvester: a plain network ([`NetworkConfig`]: its name, bit rate, seed, field nodes and
/// restarts) with the monitor, the time relay and the plant around it. A `Network(...)` file is
/// one with none of these ([`HarvesterConfig::around`]).
#[derive(Clone, Debug)]
pub struct HarvesterConfig {
    /// The network under it; its reaction time is the field nodes'.
    pub network: NetworkConfig,
    /// Delay from monitor power-up to field-node power-up, ms.
    pub time_relay_ms: u64,
    /// The monitor.
    pub monitor: MonitorConfig,
    /// The plant.
    pub plant: PlantConfig,
}

impl HarvesterConfig {
    /// A plain network as a harvester config: no monitor, no time relay (its nodes power up at
    /// once), the default plant.
    pub fn around(network: NetworkConfig) -> HarvesterConfig {
        HarvesterConfig {
            network,
            time_relay_ms: 0,
            monitor: MonitorConfig {
                enabled: false,
                ..MonitorConfig::default()
            },
            plant: PlantConfig::default(),
        }
    }
}

/// `configs/harvester.ron` as written: one flat section.
#[derive(Deserialize)]
#[serde(deny_unknown_fields, rename = "Harvester")]
struct HarvesterFile {
    /// Machine name.
    name: String,
    bitrate: u32,
    seed: u64,
    time_relay_ms: u64,
    reaction_us: u64,
    #[serde(default)]
    monitor: MonitorConfig,
    nodes: Vec<String>,
    #[serde(default)]
    plant: PlantConfig,
    #[serde(default)]
    restart: RestartPolicy,
}

impl From<HarvesterFile> for HarvesterConfig {
    fn from(f: HarvesterFile) -> HarvesterConfig {
        HarvesterConfig {
            network: NetworkConfig {
                name: f.name,
                bitrate: f.bitrate,
                nodes: f.nodes,
                seed: f.seed,
                reaction_us: f.reaction_us,
                restart: f.restart,
            },
            time_relay_ms: f.time_relay_ms,
            monitor: f.monitor,
            plant: f.plant,
        }
    }
}

/// A loaded, validated harvester.
#[derive(Clone, Debug)]
pub struct Harvester {
    /// Where it was read from.
    pub source: Source,
    /// The config.
    pub config: HarvesterConfig,
    /// The node scripts, in config order.
    pub scripts: Vec<NodeScript>,
    /// The firmware nodes, in config order.
    pub firmware: Vec<Arc<FirmwareSpec>>,
    /// Read from a `Network(...)` file: a plain bus, no harvester around it (no plant signals
    /// worth showing).
    pub network: bool,
    /// Where bus time zero lies on the wall clock in the trace and the gateway's frames; `None`
    /// for the hub's default (the wall clock in real time, [`bus::time::Epoch::FIXED`] in
    /// virtual time). A command that writes the trace itself sets it, so that both agree.
    pub epoch: Option<bus::time::Epoch>,
    /// Count the firmware nodes' code coverage ([`crate::coverage`]; off unless a command asks):
    /// [`super::Running::end_coverage`] gives it.
    pub coverage: bool,
    /// The field nodes the machine has, by name, with their addresses and start-up times (ms
    /// from power-on to the end of boot: a script's `boot_delay_ms`, a firmware node file's
    /// `start_up_ms`): what the
    /// monitor expects to hear. Nodes left out with [`Harvester::without`] stay in it, since the
    /// machine still has them (a real device is to take their place).
    pub expected: Vec<(String, Address, u64)>,
}

impl Harvester {
    /// Reads and checks a harvester config and every script it names; every problem is
    /// reported at once. `path` is read as [`Source::file`] says: from disk when something is
    /// there, else the built-in copy.
    pub fn load(path: &Path) -> Result<Harvester, Error> {
        Harvester::open(&Source::file(path))
    }

    /// [`Harvester::load`] from a source: each file is read with [`Source::read`] (from disk at
    /// most [`nodes::file::MAX_FILE`] bytes), the node scripts beside the config, in the
    /// built-in tree when the config is built in.
    pub fn open(source: &Source) -> Result<Harvester, Error> {
        let (source, text) = source.read()?;
        let signals = nodes::environment::PlantSignals;
        Harvester::parse(&source, &text, |script| {
            let (found, text) = script.read()?;
            let file = found.to_string();
            if nodes::script::top_name(&text) == Some("Firmware") {
                let spec = nodes::firmware::load(&file, &found.path, &text, &found.reader())?;
                return Ok(NodeFile::Firmware(Arc::new(spec)));
            }
            nodes::script::from_file_text(&file, &found.path, &text, &signals, &found.reader())
                .map(|s| NodeFile::Script(Box::new(s)))
        })
    }

    /// As [`Harvester::load`] with the config's text already read: `path` is where it came from
    /// (problems name it; node scripts are relative to its directory) and `script` reads, parses
    /// and validates the node script at a path, as [`nodes::script::load`] does.
    pub fn from_text(
        path: &Path,
        text: &str,
        mut script: impl FnMut(&Path) -> Result<NodeScript, Error>,
    ) -> Result<Harvester, Error> {
        Harvester::parse(&Source::file(path), text, |s| {
            script(&s.path).map(|s| NodeFile::Script(Box::new(s)))
        })
    }

    fn parse(
        source: &Source,
        text: &str,
        mut script: impl FnMut(&Source) -> Result<NodeFile, Error>,
    ) -> Result<Harvester, Error> {
        let file = source.to_string();
        let network = nodes::script::top_name(text) == Some("Network");
        let config = if network {
            HarvesterConfig::around(nodes::parse_ron::<NetworkConfig>(&file, text)?)
        } else {
            nodes::parse_ron::<HarvesterFile>(&file, text)?.into()
        };
        let mut problems = Vec::new();
        if BitRate::for_bus(config.network.bitrate).is_none() {
            problems.push(Problem::at(
                &file,
                "bitrate",
                format!("{} bit/s: {}", config.network.bitrate, BitRate::RULE),
            ));
        }
        if config.network.nodes.is_empty() {
            problems.push(Problem::at(&file, "nodes", "no nodes"));
        }
        for (field, us) in [
            ("reaction_us", config.network.reaction_us),
            ("monitor.reaction_us", config.monitor.reaction_us),
        ] {
            if us > MAX_REACTION_US {
                problems.push(Problem::at(
                    &file,
                    field,
                    format!(
                        "{us} µs is over {MAX_REACTION_US} µs (one second), the longest \
                         interrupt-to-answer time harvemu takes"
                    ),
                ));
            }
        }
        problems.extend(
            config
                .monitor
                .validate()
                .into_iter()
                .map(|(field, m)| Problem::at(&file, format!("monitor.{field}"), m)),
        );
        let restart = &config.network.restart;
        if !(restart.window_s.is_finite() && restart.window_s >= 0.0) {
            problems.push(Problem::at(
                &file,
                "restart.window_s",
                format!("{} is not a number >= 0", restart.window_s),
            ));
        }
        problems.extend(
            nodes::environment::validate_plant(&config.plant)
                .into_iter()
                .map(|(field, m)| Problem::at(&file, format!("plant.{field}"), m)),
        );
        let mut scripts = Vec::new();
        let mut places = Vec::new();
        let mut firmware = Vec::new();
        let mut firmware_places = Vec::new();
        for (i, rel) in config.network.nodes.iter().enumerate() {
            match script(&source.beside(rel)) {
                Ok(NodeFile::Script(s)) => {
                    scripts.push(*s);
                    places.push(format!("nodes[{i}] ({rel})"));
                }
                Ok(NodeFile::Firmware(f)) => {
                    firmware.push(f);
                    firmware_places.push(format!("nodes[{i}] ({rel})"));
                }
                Err(Error::Invalid(p)) => problems.extend(p),
                Err(Error::Io { path, source }) => problems.push(Problem::at(
                    &file,
                    format!("nodes[{i}]"),
                    format!("cannot read {path}: {source}"),
                )),
            }
        }
        problems.extend(clashes(&file, &scripts, &places, config.monitor.enabled));
        problems.extend(firmware_clashes(
            &file,
            &scripts,
            &places,
            &firmware,
            &firmware_places,
        ));
        if problems.is_empty() {
            let expected = scripts
                .iter()
                .filter(|s| s.database.is_none())
                .map(|s| (s.name.clone(), Address(s.address), s.boot_delay_ms))
                .chain(
                    firmware
                        .iter()
                        .filter_map(|f| f.address.map(|a| (f.name.clone(), Address(a), f.start_up_ms))),
                )
                .collect();
            Ok(Harvester {
                source: source.clone(),
                config,
                scripts,
                firmware,
                network,
                epoch: None,
                coverage: false,
                expected,
            })
        } else {
            Err(Error::Invalid(problems))
        }
    }

    /// Leaves nodes out (a real device takes each one's place); "F5" is the monitor. Names are
    /// unique (loading checks it), so each name leaves out exactly one node.
    pub fn without(&mut self, names: &[String]) -> Result<(), Error> {
        let mut problems = Vec::new();
        for n in names {
            if n == "F5" {
                self.config.monitor.enabled = false;
            } else if let Some(i) = self.scripts.iter().position(|s| &s.name == n) {
                self.scripts.remove(i);
            } else if let Some(i) = self.firmware.iter().position(|f| &f.name == n) {
                self.firmware.remove(i);
            } else {
                let file = self.source.to_string();
                problems.push(Problem::at(
                    &file,
                    "nodes",
                    format!("--without {n}: no such node"),
                ));
            }
        }
        if problems.is_empty() {
            Ok(())
        } else {
            Err(Error::Invalid(problems))
        }
    }

    /// The time at which the field nodes power up.
    pub fn relay(&self) -> BusTime {
        BusTime::from_millis(self.config.time_relay_ms)
    }

    /// Its nodes' names with the ids they take on the bus: the monitor ("F5") first when it is
    /// emulated, then the scripted nodes and the firmware nodes in config order, as they are
    /// attached (`harvester/assembly.rs`); a firmware node takes one id per chip (one without a
    /// chip, one), and its first is the node's.
    pub fn node_ids(&self) -> Vec<(String, NodeId)> {
        let mut next = 0u16;
        let mut take = |name: &str, controllers: usize| {
            let id = NodeId(next);
            next = next.saturating_add(u16::try_from(controllers.max(1)).unwrap_or(u16::MAX));
            (name.to_string(), id)
        };
        let monitor = self.config.monitor.enabled.then(|| take("F5", 1));
        let scripts: Vec<_> = self.scripts.iter().map(|s| take(&s.name, 1)).collect();
        let firmware: Vec<_> = self
            .firmware
            .iter()
            .map(|f| take(&f.name, f.chips.len()))
            .collect();
        monitor.into_iter().chain(scripts).chain(firmware).collect()
    }

    /// The names of its nodes, the monitor's ("F5") first when it is emulated.
    pub fn node_names(&self) -> Vec<String> {
        let monitor = self.config.monitor.enabled.then(|| "F5".to_string());
        monitor
            .into_iter()
            .chain(self.scripts.iter().map(|s| s.name.clone()))
            .chain(self.firmware.iter().map(|f| f.name.clone()))
            .collect()
    }
}

/// The longest reaction time a config may give (`reaction_us`, `monitor.reaction_us`): one
/// second. An MCU's interrupt latency is microseconds; far beyond a second a node would answer
/// after the run, and at 2^64 − 1 µs the hub's clock saturates and the node never hears a frame.
pub const MAX_REACTION_US: u64 = 1_000_000;

/// Nodes that would be mistaken for one another: two with one name (`--without`, scenarios and
/// traces pick nodes by name), one named F5 (the monitor's name) while the monitor runs
/// (`monitor`), two with one harvester address, or one at the monitor's address. `places[i]`
/// says where `scripts[i]` is in the config.
fn clashes(file: &str, scripts: &[NodeScript], places: &[String], monitor: bool) -> Vec<Problem> {
    let mut problems = Vec::new();
    let problem = |s: &NodeScript, place: &str, message: String| Problem {
        file: file.to_string(),
        position: None,
        node: Some(s.name.clone()),
        field: Some(place.to_string()),
        message,
    };
    let mut names = std::collections::BTreeMap::new();
    let mut addresses = std::collections::BTreeMap::new();
    for (s, place) in scripts.iter().zip(places) {
        if monitor && s.name == "F5" {
            problems.push(problem(s, place, "F5 is the monitor's name".into()));
        }
        if s.address == Address::MONITOR.0 {
            problems.push(problem(s, place, "takes the monitor's address F5".into()));
        }
        if let Some(other) = names.insert(s.name.as_str(), place) {
            problems.push(problem(
                s,
                place,
                format!("{other} has the same name: every node needs a name of its own"),
            ));
        }
        // A node of a DBC network has no harvester address.
        if s.database.is_some() {
            continue;
        }
        if let Some((other, name)) = addresses.insert(s.address, (place, &s.name)) {
            problems.push(problem(
                s,
                place,
                format!("{other} (node {name}) has the same address {:02X}", s.address),
            ));
        }
    }
    problems
}

/// What a node file holds: a behaviour script or a firmware node.
pub enum NodeFile {
    /// A behaviour script (or an instance of a template).
    Script(Box<NodeScript>),
    /// A firmware image on an emulated CPU.
    Firmware(Arc<FirmwareSpec>),
}

/// Firmware nodes whose names (or their further chips' names on the bus) or claimed addresses
/// clash with each other, with a script's or with the monitor's.
fn firmware_clashes(
    file: &str,
    scripts: &[NodeScript],
    places: &[String],
    firmware: &[Arc<FirmwareSpec>],
    firmware_places: &[String],
) -> Vec<Problem> {
    let mut problems = Vec::new();
    let mut seen: std::collections::BTreeMap<&str, &String> = scripts
        .iter()
        .zip(places)
        .map(|(s, p)| (s.name.as_str(), p))
        .collect();
    // Addresses firmware nodes claim (`address:` in their files), with where and who.
    let mut claimed: std::collections::BTreeMap<u8, (&String, &str)> = Default::default();
    for (f, place) in firmware.iter().zip(firmware_places) {
        let problem = |message: String| Problem {
            file: file.to_string(),
            position: None,
            node: Some(f.name.clone()),
            field: Some(place.clone()),
            message,
        };
        if f.name == "F5" {
            problems.push(problem("F5 is the monitor's name".into()));
        }
        if let Some(other) = seen.insert(f.name.as_str(), place) {
            problems.push(problem(format!(
                "{other} has the same name: every node needs a name of its own"
            )));
        }
        if let Some(address) = f.address {
            if address == Address::MONITOR.0 {
                problems.push(problem("takes the monitor's address F5".into()));
            }
            let owner = scripts
                .iter()
                .zip(places)
                .find(|(s, _)| s.address == address)
                .map(|(s, p)| (p, s.name.as_str()))
                .or_else(|| claimed.get(&address).copied());
            if let Some((other, name)) = owner {
                problems.push(problem(format!(
                    "{other} (node {name}) has the same address {address:02X}"
                )));
            }
            claimed.entry(address).or_insert((place, f.name.as_str()));
        }
    }
    // A firmware node's further chips are controllers on the bus with names of their own.
    for (f, place) in firmware.iter().zip(firmware_places) {
        for k in 1..f.chips.len() {
            let chip = f.controller_name(k);
            if let Some(other) = seen.get(chip.as_str()) {
                problems.push(Problem {
                    file: file.to_string(),
                    position: None,
                    node: Some(f.name.clone()),
                    field: Some(place.clone()),
                    message: format!("its controllers[{k}] is {chip} on the bus, the name of {other}"),
                });
            }
        }
    }
    problems
}

#[cfg(test)]
mod tests {
    use super::*;

    const CONFIG: &str = r#"Harvester(name: "x", bitrate: 250000, seed: 1, time_relay_ms: 500,
        reaction_us: 200, nodes: ["nodes/d0.ron", "nodes/missing.ron"])"#;

    fn real(path: &Path) -> Result<NodeScript, Error> {
        let file = Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../configs")
            .join(path);
        nodes::script::load(&file, &nodes::environment::PlantSignals)
    }

    #[test]
    fn from_text_reads_scripts_beside_the_config_through_the_caller() {
        let mut asked = Vec::new();
        let result = Harvester::from_text(Path::new("cfg/harvester.ron"), CONFIG, |p| {
            asked.push(p.to_path_buf());
            real(p.strip_prefix("cfg").unwrap())
        });
        assert_eq!(
            asked,
            [Path::new("cfg/nodes/d0.ron"), Path::new("cfg/nodes/missing.ron")]
        );
        let Err(Error::Invalid(problems)) = result else {
            panic!("a missing script is a problem");
        };
        assert_eq!(problems.len(), 1);
        assert_eq!(problems[0].file, "cfg/harvester.ron");
        assert_eq!(problems[0].field.as_deref(), Some("nodes[1]"));
    }

    /// The config's problems, as text, with scripts read by `script`.
    fn problems(text: &str, script: impl FnMut(&Path) -> Result<NodeScript, Error>) -> Vec<String> {
        match Harvester::from_text(Path::new("h.ron"), text, script) {
            Ok(_) => Vec::new(),
            Err(e) => e
                .to_string()
                .lines()
                .skip(1)
                .map(|l| l.trim().to_string())
                .collect(),
        }
    }

    /// Three scripts: d0.ron as itself, and as copies renamed or readdressed by the file name.
    fn three(p: &Path) -> Result<NodeScript, Error> {
        let mut s = real(Path::new("nodes/d0.ron"))?;
        match p.file_name().and_then(|n| n.to_str()) {
            Some("b.ron") => s.address = 0xD1,
            Some("c.ron") => s.name = "F5".into(),
            _ => {}
        }
        Ok(s)
    }

    const THREE: &str = r#"Harvester(name: "x", bitrate: 250000, seed: 1, time_relay_ms: 500,
        reaction_us: 200, nodes: ["a.ron", "b.ron", "c.ron"])"#;

    /// `--without D0` removed the first D0 and left the other running: names must be unique.
    #[test]
    fn two_nodes_with_one_name_or_address_are_refused_with_both_places() {
        assert_eq!(
            problems(THREE, three),
            [
                "h.ron: node D0: nodes[1] (b.ron): nodes[0] (a.ron) has the same name: every node \
                 needs a name of its own",
                "h.ron: node F5: nodes[2] (c.ron): F5 is the monitor's name",
                "h.ron: node F5: nodes[2] (c.ron): nodes[0] (a.ron) (node D0) has the same address D0",
            ]
        );
    }

    #[test]
    fn a_reaction_time_over_a_second_is_refused() {
        let one = |t: &str| t.replace(r#", "b.ron", "c.ron""#, "");
        assert!(problems(&one(THREE).replace("200", "1000000"), three).is_empty());
        let text = one(THREE).replace(
            "reaction_us: 200",
            "reaction_us: 18446744073709551615, \
            monitor: (reaction_us: 1000001)",
        );
        assert_eq!(
            problems(&text, three),
            [
                "h.ron: reaction_us: 18446744073709551615 µs is over 1000000 µs (one second), \
                 the longest interrupt-to-answer time harvemu takes",
                "h.ron: monitor.reaction_us: 1000001 µs is over 1000000 µs (one second), the \
                 longest interrupt-to-answer time harvemu takes",
            ]
        );
    }

    #[test]
    fn every_rate_with_an_exact_bit_time_is_taken_and_the_message_says_so() {
        let one = THREE.replace(r#", "b.ron", "c.ron""#, "");
        // 30 kbit/s (an 80C51 + SJA1000 board's rate) has a bit time of 33 333.3 ns.
        for ok in [10_000, 30_000, 50_000, 100_000, 125_000, 800_000, 1_000_000] {
            let text = one.replace("250000", &ok.to_string());
            assert!(problems(&text, three).is_empty(), "{ok}");
        }
        // 7 and 33.3 kbit/s have primes other than 2, 3 and 5 in them (7, 37).
        for bad in [0, 7_000, 9_999, 33_300, 70_000, 2_000_000] {
            let text = one.replace("250000", &bad.to_string());
            let p = problems(&text, three);
            assert_eq!(p.len(), 1, "{p:?}");
            assert!(
                p[0].starts_with(&format!("h.ron: bitrate: {bad} bit/s: a bit rate must be 10000 to 1000000 bit/s with a bit time the bus clock holds exactly")),
                "{p:?}"
            );
        }
    }

    /// Values the monitor sends must fit the field that carries them, and the plant input the
    /// receiving node writes them to: otherwise the monitor cannot encode them and stays silent.
    #[test]
    fn monitor_values_outside_what_carries_them_are_refused() {
        let text = THREE.replace(r#", "b.ron", "c.ron""#, "").replace(
            "reaction_us: 200,",
            "reaction_us: 200, monitor: (target_reference: 0, \
             cruise: (min_kmh: 9.0, max_kmh: 20.0, step_kmh: inf)),",
        );
        assert_eq!(
            problems(&text, three),
            [
                "h.ron: monitor.target_reference: 0 is outside 1..=65535, what \
                 flow.calibrate.target_reference and plant input sensor.target_reference can carry",
                "h.ron: monitor.cruise.max_kmh: 20 is outside 0..=12, what speed.setpoint.setpoint \
                 and plant input speed.setpoint can carry",
                "h.ron: monitor.cruise.step_kmh: inf is not a number >= 0",
            ]
        );
        let inverted = THREE.replace(r#", "b.ron", "c.ron""#, "").replace(
            "reaction_us: 200,",
            "reaction_us: 200, monitor: (cruise: (min_kmh: 6.0, max_kmh: 2.0)),",
        );
        assert_eq!(
            problems(&inverted, three),
            ["h.ron: monitor.cruise.min_kmh: 6 is above cruise.max_kmh 2"]
        );
    }

    /// A huge time relay loaded, then overflowed the bus clock when the run computed it.
    #[test]
    fn a_huge_time_relay_is_never_rather_than_an_overflow() {
        let text = CONFIG
            .replace("time_relay_ms: 500", "time_relay_ms: 18446744073709551615")
            .replace(r#", "nodes/missing.ron""#, "");
        let h = Harvester::from_text(Path::new("harvester.ron"), &text, real).unwrap();
        assert_eq!(h.scripts.len(), 1);
        assert_eq!(h.relay(), BusTime::NEVER);
    }
}
