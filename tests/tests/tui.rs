//! The live display (`harvemu run --tui`) rendered from real virtual-time runs of the default
//! harvester: what the screen shows is checked against the plant, the monitor's display model
//! and the recorded trace, each formatted here.

use bus::time::BusTime;
use harvemu_e2e::{Line, default_harvester, run_virtual};
use protocol::catalogue;
use ratatui::Terminal;
use ratatui::backend::TestBackend;
use supervisor::tui::{Clock, RateMeter, Sources, View, draw};

/// Renders the running harvester as the live display would, into a 200x60 buffer.
fn screen(running: &supervisor::harvester::Running, snap: &bus_runtime::hub::Snapshot) -> Vec<String> {
    let mut rates = RateMeter::default();
    rates.update(snap);
    let display = running.display.as_ref().map(|d| d.borrow());
    let plant = running.plant.borrow();
    let view = View::build(&Sources {
        machine: "4MZ-6A",
        clock: Clock::Virtual,
        finished: true,
        snapshot: snap,
        display: display.as_deref(),
        plant: &plant,
        rates: &rates,
        events: &running.events,
        database: None,
    });
    let mut terminal = Terminal::new(TestBackend::new(200, 60)).unwrap();
    terminal.draw(|f| draw(f, &view)).unwrap();
    let buffer = terminal.backend().buffer();
    buffer
        .content()
        .chunks(200)
        .map(|row| row.iter().map(|c| c.symbol()).collect())
        .collect()
}

fn line_with<'a>(screen: &'a [String], key: &str) -> &'a str {
    let found: Vec<&String> = screen.iter().filter(|l| l.contains(key)).collect();
    assert_eq!(found.len(), 1, "one line with {key:?} in:\n{}", screen.join("\n"));
    found[0]
}

/// The monitor panel's part of a line, up to its right border (the bus panel is to its right).
fn left(line: &str) -> String {
    line.chars().skip(1).take_while(|c| *c != '│').collect()
}

#[test]
fn a_30_s_run_shows_the_plant_the_monitor_and_the_bus() {
    let until = BusTime::from_secs(30);
    let (trace, (screen, speed, total_kg, load, frames)) = run_virtual(
        default_harvester(),
        until,
        |_| {},
        |running, snap| {
            let speed = running.plant.borrow().signal("speed.actual").unwrap();
            let total_kg = running.display.as_ref().unwrap().borrow().total_kg;
            (
                screen(running, snap),
                speed,
                total_kg,
                snap.stats.total_load(),
                snap.stats.frames,
            )
        },
    );
    assert!(speed > 1.0, "the harvester moves: {speed} km/h");
    let speed_line = left(line_with(&screen, "travel speed"));
    assert!(speed_line.contains(&format!(" {speed:.1} ")), "{speed_line}");
    let total = left(line_with(&screen, "harvested"));
    assert!(total.contains(&format!(" {total_kg:.1} ")), "{total}");
    line_with(&screen, &format!("load {:.1} %", load * 100.0));
    assert_eq!(frames as usize, trace.len(), "the trace holds every frame");
    line_with(&screen, &format!("frames {frames} "));

    // The speed controller's status: its last frame in the trace, decoded and formatted here.
    let status: Vec<&Line> = trace.iter().filter(|l| l.frame.raw_id() == 0x0200F5E0).collect();
    let last = status.last().unwrap().frame;
    let row = line_with(&screen, "0200F5E0");
    let hex: Vec<String> = last.data().iter().map(|b| format!("{b:02X}")).collect();
    assert!(row.contains(&hex.join(" ")), "{row}");
    let decoded = catalogue::decode(&last).unwrap().unwrap();
    let actual = decoded.get("actual").unwrap().physical;
    assert!(row.contains(&format!("actual={actual:.2} km/h")), "{row}");
    assert!(row.contains("speed.status") && row.contains("E0>F5"), "{row}");
    // With one snapshot the rate is the mean over the run: frames less one over their span.
    let span = (status.last().unwrap().at - status[0].at).as_secs_f64();
    let rate = (status.len() - 1) as f64 / span;
    assert!(row.contains(&format!(" {rate:.1} ")), "{rate:.1} fr/s in {row}");
    // Nothing went wrong: every node is error active with clean counters.
    for name in ["F5", "E0", "D5"] {
        line_with(&screen, &format!("{name} active 0/0"));
    }
    line_with(&screen, "no active alarm");
}

#[test]
fn a_stopped_conveyor_belt_raises_an_alarm_on_screen() {
    let (_, (screen, alarms)) = run_virtual(
        default_harvester(),
        BusTime::from_secs(10),
        |running| {
            running
                .plant
                .borrow_mut()
                .set_input("fault.belt_stop", 1.0)
                .unwrap();
        },
        |running, snap| {
            let display = running.display.as_ref().unwrap().borrow();
            let active: Vec<_> = display.active_alarms().cloned().collect();
            drop(display);
            (screen(running, snap), active)
        },
    );
    let belt = alarms
        .iter()
        .find(|a| a.node == "C2" && a.name == "belt_stopped")
        .expect("the monitor raised the alarm");
    line_with(
        &screen,
        &format!("ALARM C2 belt_stopped since {:.1} s", belt.raised.as_secs_f64()),
    );
    assert!(line_with(&screen, "0400F5C2").contains("belt_stopped=on"));
}

#[test]
fn the_seed_lab_with_firmware_on_both_benches_shows_on_screen() {
    let lab =
        supervisor::harvester::Harvester::load(&harvemu_e2e::root().join("configs/firmware/seed_lab.ron"))
            .expect("the seed lab loads");
    // The sender's frames end at 4.003 ms and every 99.916 ms after (docs/FIRMWARE.md): ten by
    // 0.95 s, the eleventh not begun.
    let until = BusTime::from_micros(950_000);
    let (trace, screen) = run_virtual(lab, until, |_| {}, screen);
    assert_eq!(trace.len(), 10, "{trace:?}");
    line_with(&screen, &format!("frames {} ", trace.len()));
    // The seed's frame: identifier 5DFh, its eight bytes as the seed's result analysis has them.
    let row = line_with(&screen, "5DF");
    assert!(row.contains("AA BB CC D4 E5 F6 97 18"), "{row}");
    for name in ["SENDER", "RECEIVER"] {
        line_with(&screen, &format!("{name} active 0/0"));
    }
}

/// A network imported from a DBC has no monitor: the live display shows its bus, each node's
/// controller and the DBC's messages, with the last frame of each as the trace has it.
#[test]
fn an_imported_network_shows_its_bus_without_a_monitor() {
    const DBC: &str = r#"VERSION ""
NS_ :
BS_:
BU_: ENGINE BRAKE
BO_ 2566844926 EEC1: 8 ENGINE
 SG_ EngineSpeed : 24|16@1+ (0.125,0) [0|8031.875] "rpm" BRAKE
BO_ 256 Brake: 2 BRAKE
 SG_ Pressure : 7|16@0+ (0.01,0) [0|655.35] "bar" ENGINE
BA_DEF_ BO_ "GenMsgCycleTime" INT 0 65535;
BA_DEF_DEF_ "GenMsgCycleTime" 0;
BA_ "GenMsgCycleTime" BO_ 2566844926 20;
BA_ "GenMsgCycleTime" BO_ 256 100;
"#;
    let dir = std::env::temp_dir().join(format!("harvemu-tui-imported-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(dir.join("nodes")).unwrap();
    std::fs::write(dir.join("truck.dbc"), DBC).unwrap();
    let db = protocol::database::Database::parse("truck.dbc", DBC).unwrap();
    let plan = supervisor::import::plan(&db, "truck.dbc", "truck", supervisor::import::Signals::Ramp);
    for f in &plan.files {
        std::fs::write(dir.join(&f.path), &f.text).unwrap();
    }
    let h = supervisor::harvester::Harvester::load(&dir.join("network.ron")).unwrap();
    let (trace, screen) = run_virtual(
        h,
        BusTime::from_secs(5),
        |_| {},
        |running, snap| {
            let mut rates = RateMeter::default();
            rates.update(snap);
            let plant = running.plant.borrow();
            assert!(running.display.is_none(), "a network has no monitor");
            let view = View::build(&Sources {
                machine: "truck",
                clock: Clock::Virtual,
                finished: true,
                snapshot: snap,
                display: None,
                plant: &plant,
                rates: &rates,
                events: &running.events,
                database: running.database(),
            });
            let mut terminal = Terminal::new(TestBackend::new(200, 60)).unwrap();
            terminal.draw(|f| draw(f, &view)).unwrap();
            let buffer = terminal.backend().buffer();
            buffer
                .content()
                .chunks(200)
                .map(|row| row.iter().map(|c| c.symbol()).collect::<String>())
                .collect::<Vec<_>>()
        },
    );
    let _ = std::fs::remove_dir_all(&dir);
    for name in ["ENGINE", "BRAKE"] {
        line_with(&screen, &format!("{name} active 0/0"));
    }
    // Each message's row: its name, its transmitter, the last payload of the trace and its
    // signal decoded here from the DBC's layout (EngineSpeed: bytes 3..4 low first, 0.125 rpm;
    // Pressure: bytes 0..1 high first, 0.01 bar).
    for (id, name, from) in [(0x18FE_F1FE, "EEC1", "ENGINE"), (0x100, "Brake", "BRAKE")] {
        let last = trace.iter().rev().find(|l| l.frame.raw_id() == id).unwrap().frame;
        let d = last.data();
        let hex: Vec<String> = d.iter().map(|b| format!("{b:02X}")).collect();
        let decoded = if id == 0x100 {
            format!(
                "Pressure={:.2} bar",
                f64::from(u16::from_be_bytes([d[0], d[1]])) * 0.01
            )
        } else {
            format!(
                "EngineSpeed={:.3} rpm",
                f64::from(u16::from_le_bytes([d[3], d[4]])) * 0.125
            )
        };
        let key = if id > 0x7FF {
            format!("{id:08X}")
        } else {
            format!("     {id:03X}")
        };
        let row = line_with(&screen, &key);
        for part in [name, from, &hex.join(" "), &decoded] {
            assert!(row.contains(part), "{part} in {row}\n{}", screen.join("\n"));
        }
    }
}
