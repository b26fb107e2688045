//! SDCC's debug records of a real build, read by `nodes::firmware::debuginfo`, against a second
//! source: the linker's map (`.map`), which places every global function. C0's source built
//! with `--debug` gives both.

use harvemu_e2e::root;
use nodes::firmware::debuginfo;
use std::collections::HashMap;
use std::process::Command;

#[test]
fn the_cdb_of_c0_agrees_with_the_linker_map() {
    let dir = std::env::temp_dir().join(format!("harvemu-cdb-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    for file in ["c0_alarm.c", "at89c51cc03.h"] {
        let from = root().join("configs/firmware/c0").join(file);
        std::fs::copy(&from, dir.join(file)).unwrap_or_else(|e| panic!("{}: {e}", from.display()));
    }
    let out = Command::new("sdcc")
        .current_dir(&dir)
        .args(["-mmcs51", "--model-small", "--debug", "c0_alarm.c"])
        .output()
        .unwrap_or_else(|e| panic!("cannot run sdcc ({e}): install the Debian package sdcc"));
    assert!(
        out.status.success(),
        "sdcc: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let read = |name: &str| std::fs::read_to_string(dir.join(name)).unwrap_or_else(|e| panic!("{name}: {e}"));
    let info = debuginfo::parse("c0_alarm.cdb", &read("c0_alarm.cdb")).unwrap();
    // The map's code symbols: `C:   000001D7  _main   c0_alarm`.
    let map: HashMap<String, u16> = read("c0_alarm.map")
        .lines()
        .filter_map(|l| {
            let mut f = l.strip_prefix("C:")?.split_whitespace();
            let address = u16::from_str_radix(f.next()?, 16).ok()?;
            Some((f.next()?.to_string(), address))
        })
        .collect();
    let _ = std::fs::remove_dir_all(&dir);

    // The functions of c0_alarm.c: the global ones, and the static ones of module c0_alarm.
    let mut names: Vec<(Option<&str>, &str)> = info
        .functions
        .iter()
        .map(|f| (f.module.as_deref(), f.name.as_str()))
        .collect();
    names.sort();
    let statics = [
        "adc_read",
        "can_service",
        "can_setup",
        "check",
        "send_frame",
        "vacuum_mv",
    ];
    let mut expected: Vec<(Option<&str>, &str)> = statics.iter().map(|n| (Some("c0_alarm"), *n)).collect();
    expected.extend([
        (None, "_sdcc_external_startup"),
        (None, "main"),
        (None, "timer2_isr"),
    ]);
    expected.sort();
    assert_eq!(names, expected);
    for f in info.functions.iter().filter(|f| f.module.is_none()) {
        assert_eq!(Some(&f.start), map.get(&format!("_{}", f.name)), "{}", f.name);
    }
    // Every function's code ends after it starts, and every source line's code lies in one.
    for f in &info.functions {
        assert!(f.end.is_some_and(|e| e >= f.start), "{f:?}");
    }
    assert!(info.lines.len() > 50, "{} lines", info.lines.len());
    for l in &info.lines {
        assert_eq!(l.file, "c0_alarm.c");
        let inside = info
            .functions
            .iter()
            .filter(|f| f.start <= l.address && f.end.is_some_and(|e| l.address <= e))
            .count();
        assert_eq!(inside, 1, "{l:?}");
    }
}
