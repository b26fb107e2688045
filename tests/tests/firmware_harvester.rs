//! A firmware node in the harvester, in the place of one of the 20 scripted nodes: the
//! interrupt-driven receiver of `configs/firmware/` set to the harvester's 250 kbit/s (a 16 MHz
//! SJA1000 crystal, BTR0 = 01h, BTR1 = 1Ch: 16 MHz / (2 · 2 · 16 quanta)) and to accept every
//! frame (AMR0 = FFh). It takes C3's place, runs beside the other nodes without disturbing the
//! bus, and its handler sees every frame the bus carries.

use bus::time::BusTime;
use bus_runtime::hub::{GetSnapshot, RunUntil};
use harvemu_e2e::{assemble, default_harvester, drive, firmware_spec, parse_trace, root};

#[test]
fn a_firmware_node_takes_a_scripted_nodes_place() {
    let source = std::fs::read_to_string(root().join("configs/firmware/irq_receiver.asm")).expect("asm");
    let patched = source
        .replacen("MOV     A, #03H", "MOV     A, #01H", 1)
        .replacen("MOV     A, #0FFH", "MOV     A, #1CH", 1)
        // AMR0 is written from A = 00h after `CLR A`: make it FFh, all bits don't care.
        .replacen("        CLR     A\n", "        MOV     A, #0FFH\n", 1);
    assert_eq!(
        patched.matches("#01H").count(),
        source.matches("#01H").count() + 1
    );
    let hex = assemble(&patched);
    let text = "Firmware(name: \"C3\", image: \"fw.hex\", entry: None, cpu: I80C51(clock_hz: 12000000), \
                controllers: [Sja1000(base: 0xD400, xtal_hz: 16000000, irq: Some(Int0))])";
    let mut h = default_harvester();
    h.scripts.retain(|s| s.name != "C3");
    h.firmware.push(firmware_spec("c3.ron", text, "fw.hex", &hex));
    let relay = h.relay();
    let end = BusTime::from_secs(20);
    let (trace, (snap, state)) = drive(h, async move |running| {
        running.hub.send(RunUntil(end)).await.expect("hub").expect("run");
        let snap = running.hub.send(GetSnapshot).await.expect("snapshot");
        let state = running.hardware(end).await;
        (snap, state)
    });
    let frames = parse_trace(&trace);
    assert!(frames.len() > 1000, "{} frames", frames.len());
    // Nothing disturbed: no error frame, every node error active, the firmware's included.
    assert_eq!(snap.stats.error_frames, 0);
    assert!(
        snap.nodes
            .iter()
            .all(|n| n.state == bus::fault::ErrorState::Active)
    );
    let (name, hw) = &state[0];
    assert_eq!(name, "C3");
    assert_eq!((hw.controllers[0].tec, hw.controllers[0].rec), (0, 0));
    // Its handler counted in R5 every frame that ended after the chip joined the bus (a few
    // hundred microseconds after the time relay powered it up), modulo 256.
    let joined = relay + bus::time::BusDuration::from_millis(1);
    let heard = frames.iter().filter(|f| f.at > joined && f.at <= end).count();
    let r5 = u8::from_str_radix(&hw.cpu.iram[10..12], 16).expect("hex");
    assert_eq!(r5, (heard % 256) as u8, "{heard} frames after {joined}");
}
