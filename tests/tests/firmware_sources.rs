//! The field nodes' C firmware (configs/firmware/KIND/KIND.c, one source per kind): each shipped
//! image (configs/firmware/KIND.hex) is what Debian's SDCC makes of its source with the command
//! its opening comment gives, so no HEX drifts from its C; no image writes the page FF00h–FFFFh
//! the node files' configuration blocks take; and every node file of the firmware harvester
//! loads, claims the address its name says, and places its block there.

use harvemu_e2e::root;
use std::path::Path;
use std::process::Command;

/// Code memory of the AT89C51CC03: 64 KB of flash.
const CODE_BYTES: usize = 0x1_0000;
/// Where the node files place their configuration blocks.
const BLOCK: u32 = 0xFF00;

const KINDS: [&str; 5] = [
    "flow_sensor",
    "row_alignment",
    "parameter_module",
    "alarm_module",
    "speed_control",
];

/// The folder of a kind's source (the parameter and alarm modules' sources sit in folders
/// named after the module).
fn folder(kind: &str) -> &str {
    match kind {
        "parameter_module" => "parameter",
        "alarm_module" => "alarm",
        other => other,
    }
}

fn image(text: &str, what: &str) -> mcs51::Image {
    mcs51::hex::parse(text, CODE_BYTES).unwrap_or_else(|e| panic!("{what}: {e}"))
}

fn build(kind: &str) -> mcs51::Image {
    let dir = std::env::temp_dir().join(format!("harvemu-src-{kind}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(dir.join("src")).unwrap();
    std::fs::create_dir_all(dir.join("c0")).unwrap();
    let source = root()
        .join("configs/firmware")
        .join(folder(kind))
        .join(format!("{kind}.c"));
    std::fs::copy(&source, dir.join("src").join(format!("{kind}.c")))
        .unwrap_or_else(|e| panic!("{}: {e}", source.display()));
    // The sources include ../c0/at89c51cc03.h.
    std::fs::copy(
        root().join("configs/firmware/c0/at89c51cc03.h"),
        dir.join("c0/at89c51cc03.h"),
    )
    .unwrap();
    let out = Command::new("sdcc")
        .current_dir(dir.join("src"))
        .args([
            "-mmcs51",
            "--model-small",
            "-o",
            &format!("{kind}.ihx"),
            &format!("{kind}.c"),
        ])
        .output()
        .unwrap_or_else(|e| panic!("cannot run sdcc ({e}): install the Debian package sdcc"));
    assert!(
        out.status.success(),
        "sdcc failed on {kind}.c:\n{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    let made = std::fs::read_to_string(dir.join("src").join(format!("{kind}.ihx"))).unwrap();
    let made = image(&made, &format!("{kind}.ihx made by sdcc"));
    std::fs::remove_dir_all(&dir).unwrap();
    made
}

#[test]
fn sdcc_makes_every_shipped_image_from_its_source() {
    for kind in KINDS {
        let made = build(kind);
        let path = root().join("configs/firmware").join(format!("{kind}.hex"));
        let shipped = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        let shipped = image(&shipped, &path.display().to_string());
        assert_eq!(
            made.written, shipped.written,
            "{kind}: sdcc writes other addresses"
        );
        let differ: Vec<String> = (0..CODE_BYTES)
            .filter(|&a| made.code[a] != shipped.code[a])
            .take(8)
            .map(|a| {
                format!(
                    "{a:04X}H: sdcc {:02X}, shipped {:02X}",
                    made.code[a], shipped.code[a]
                )
            })
            .collect();
        assert!(differ.is_empty(), "{kind}.hex is not what sdcc makes: {differ:?}");
        assert_eq!(shipped.code[0], 0x02, "{kind}: no LJMP at the reset vector");
        assert!(
            shipped.written.iter().all(|r| r.end <= BLOCK),
            "{kind}: the image writes the configuration page: {:?}",
            shipped.written
        );
    }
}

#[test]
fn every_node_file_of_the_firmware_harvester_claims_its_address_and_places_its_block() {
    let dir = root().join("configs/firmware/harvester");
    let mut names: Vec<String> = std::fs::read_dir(&dir)
        .expect("configs/firmware/harvester")
        .map(|e| e.expect("an entry").file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".ron"))
        .collect();
    names.sort();
    assert_eq!(names.len(), 20, "twenty field nodes: {names:?}");
    for name in names {
        let path = dir.join(&name);
        let text = std::fs::read_to_string(&path).expect("the node file");
        let read = |p: &Path| nodes::script::disk(p);
        let spec =
            nodes::firmware::load(&name, &path, &text, &read).unwrap_or_else(|e| panic!("{name}: {e}"));
        let stem = name.trim_end_matches(".ron").to_uppercase();
        assert_eq!(spec.name, stem, "{name}");
        let want = u8::from_str_radix(&stem, 16).expect("a node name is its address");
        assert_eq!(spec.address, Some(want), "{name}");
        assert!(
            spec.image.written.iter().any(|r| r.start == BLOCK),
            "{name}: no configuration block at FF00h"
        );
        assert_eq!(spec.variant, mcs51::Variant::At89c51cc03, "{name}");
    }
}
