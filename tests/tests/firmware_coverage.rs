//! Code coverage of firmware nodes is exact: an instruction counted as run ran, as often as
//! counted, with a run ahead sent back by frames, a delay loop passed in closed form and an
//! idle loop parked in, with skipping on and off.
//!
//! A small C program compiled by SDCC is counted as exactly, through its debug records: each
//! line's count in the lcov tracefile is what the C says it must be.
//!
//! The assembler program is written here and assembled with as31: an interrupt-driven receiver (as
//! `configs/firmware/irq_receiver.asm`) that first waits in a `DJNZ R7,$` delay loop, and whose
//! INT0 handler takes one branch at its fifth frame. The lab sender (`configs/firmware/`) sends
//! ten frames by 1 s (see `firmware_interrupts.rs`). Every instruction's expected count is
//! written below, by hand, with its machine cycles from the MCS-51 manual; only the idle loop's
//! count follows from the others: the CPU is never without an instruction or an interrupt
//! entry, so its SJMPs fill the cycles the rest leave before the end.

use harvemu_e2e::{assemble, bench_file, bench_specs, root, run_firmware_covered};
use nodes::firmware::coverage::{Count, Counts};
use std::sync::Arc;

const PROGRAM: &str = "
        .org    0000H
        LJMP    START
        .org    0003H
        LJMP    ISR0
        .org    0030H
START:  MOV     R7, #200
DELAY:  DJNZ    R7, DELAY
        MOV     SP, #60H
        MOV     DPTR, #0D400H
        MOV     A, #09H
        MOVX    @DPTR, A
        MOV     DPL, #1FH
        MOV     A, #88H
        MOVX    @DPTR, A
        MOV     DPL, #04H
        MOV     A, #01H
        MOVX    @DPTR, A
        MOV     DPL, #06H
        MOV     A, #03H
        MOVX    @DPTR, A
        INC     DPTR
        MOV     A, #0FFH
        MOVX    @DPTR, A
        MOV     DPL, #14H
        MOVX    @DPTR, A
        INC     DPTR
        MOVX    @DPTR, A
        INC     DPTR
        MOVX    @DPTR, A
        INC     DPTR
        MOVX    @DPTR, A
        MOV     DPL, #00H
        MOV     A, #08H
        MOVX    @DPTR, A
        MOV     R5, #00H
        CLR     88H
        SETB    0A8H
        SETB    0AFH
IDLE:   SJMP    IDLE
ISR0:   PUSH    ACC
        PUSH    DPL
        PUSH    DPH
        MOV     DPTR, #0D403H
        MOVX    A, @DPTR
        MOV     DPTR, #0D413H
        MOV     R0, #30H
        MOV     R2, #08H
COPY:   MOVX    A, @DPTR
        MOV     @R0, A
        INC     R0
        INC     DPTR
        DJNZ    R2, COPY
        MOV     DPTR, #0D401H
        MOV     A, #04H
        MOVX    @DPTR, A
        INC     R5
        CJNE    R5, #5, NOTFIVE
        MOV     40H, SP
NOTFIVE: POP    DPH
        POP     DPL
        POP     ACC
        RETI
";

/// The idle loop `IDLE: SJMP IDLE`.
const IDLE: u16 = 0x006B;

/// (address, machine cycles, runs, jumped, fell through), by hand from as31's listing; the
/// idle loop is left out.
const EXPECTED: &[(u16, u64, u64, u64, u64)] = &[
    (0x0000, 2, 1, 0, 0),     // LJMP START
    (0x0003, 2, 10, 0, 0),    // LJMP ISR0: once per frame
    (0x0030, 1, 1, 0, 0),     // MOV R7,#200
    (0x0032, 2, 200, 199, 1), // DJNZ R7,DELAY: 200 turns, the last falls through
    (0x0034, 2, 1, 0, 0),     // MOV SP,#60H
    (0x0037, 2, 1, 0, 0),     // MOV DPTR,#0D400H
    (0x003A, 1, 1, 0, 0),     // MOV A,#09H
    (0x003C, 2, 1, 0, 0),     // MOVX @DPTR,A
    (0x003D, 2, 1, 0, 0),     // MOV DPL,#1FH
    (0x0040, 1, 1, 0, 0),     // MOV A,#88H
    (0x0042, 2, 1, 0, 0),     // MOVX
    (0x0043, 2, 1, 0, 0),     // MOV DPL,#04H
    (0x0046, 1, 1, 0, 0),     // MOV A,#01H
    (0x0048, 2, 1, 0, 0),     // MOVX
    (0x0049, 2, 1, 0, 0),     // MOV DPL,#06H
    (0x004C, 1, 1, 0, 0),     // MOV A,#03H
    (0x004E, 2, 1, 0, 0),     // MOVX
    (0x004F, 2, 1, 0, 0),     // INC DPTR
    (0x0050, 1, 1, 0, 0),     // MOV A,#0FFH
    (0x0052, 2, 1, 0, 0),     // MOVX
    (0x0053, 2, 1, 0, 0),     // MOV DPL,#14H
    (0x0056, 2, 1, 0, 0),     // MOVX
    (0x0057, 2, 1, 0, 0),     // INC DPTR
    (0x0058, 2, 1, 0, 0),     // MOVX
    (0x0059, 2, 1, 0, 0),     // INC DPTR
    (0x005A, 2, 1, 0, 0),     // MOVX
    (0x005B, 2, 1, 0, 0),     // INC DPTR
    (0x005C, 2, 1, 0, 0),     // MOVX
    (0x005D, 2, 1, 0, 0),     // MOV DPL,#00H
    (0x0060, 1, 1, 0, 0),     // MOV A,#08H
    (0x0062, 2, 1, 0, 0),     // MOVX
    (0x0063, 1, 1, 0, 0),     // MOV R5,#00H
    (0x0065, 1, 1, 0, 0),     // CLR IT0
    (0x0067, 1, 1, 0, 0),     // SETB EX0
    (0x0069, 1, 1, 0, 0),     // SETB EA
    (0x006D, 2, 10, 0, 0),    // PUSH ACC
    (0x006F, 2, 10, 0, 0),    // PUSH DPL
    (0x0071, 2, 10, 0, 0),    // PUSH DPH
    (0x0073, 2, 10, 0, 0),    // MOV DPTR,#0D403H
    (0x0076, 2, 10, 0, 0),    // MOVX A,@DPTR
    (0x0077, 2, 10, 0, 0),    // MOV DPTR,#0D413H
    (0x007A, 1, 10, 0, 0),    // MOV R0,#30H
    (0x007C, 1, 10, 0, 0),    // MOV R2,#08H
    (0x007E, 2, 80, 0, 0),    // COPY: MOVX A,@DPTR, eight bytes a frame
    (0x007F, 1, 80, 0, 0),    // MOV @R0,A
    (0x0080, 1, 80, 0, 0),    // INC R0
    (0x0081, 2, 80, 0, 0),    // INC DPTR
    (0x0082, 2, 80, 70, 10),  // DJNZ R2,COPY: back seven times a frame
    (0x0084, 2, 10, 0, 0),    // MOV DPTR,#0D401H
    (0x0087, 1, 10, 0, 0),    // MOV A,#04H
    (0x0089, 2, 10, 0, 0),    // MOVX @DPTR,A
    (0x008A, 1, 10, 0, 0),    // INC R5
    (0x008B, 2, 10, 9, 1),    // CJNE R5,#5,NOTFIVE: falls through at the fifth frame
    (0x008E, 2, 1, 0, 0),     // MOV 40H,SP
    (0x0091, 2, 10, 0, 0),    // POP DPH
    (0x0093, 2, 10, 0, 0),    // POP DPL
    (0x0095, 2, 10, 0, 0),    // POP ACC
    (0x0097, 2, 10, 0, 0),    // RETI
];

/// Machine cycles of one interrupt entry (the manual's hardware LCALL), and the entries.
const ENTRY_CYCLES: u64 = 2;
const ENTRIES: u64 = 10;
/// The run: 1 s at 12 MHz, one machine cycle a microsecond.
const END_CYCLE: u64 = 1_000_000;

fn expected() -> Counts {
    let mut counts = Counts::default();
    let mut busy = ENTRY_CYCLES * ENTRIES;
    for &(addr, cycles, runs, taken, not_taken) in EXPECTED {
        counts.add(
            addr,
            Count {
                runs,
                taken,
                not_taken,
            },
        );
        busy += cycles * runs;
    }
    // The SJMPs that start before the end fill what the rest leave (two cycles each).
    let idle = (END_CYCLE - busy).div_ceil(2);
    counts.add(
        IDLE,
        Count {
            runs: idle,
            taken: 0,
            not_taken: 0,
        },
    );
    counts
}

/// The lab's sender and [`PROGRAM`] on the receiving bench, its INT output wired to INT0.
fn benches() -> Vec<Arc<nodes::firmware::FirmwareSpec>> {
    let sender = (
        bench_file("SENDER", 0x4000, 0xD300, 6_000_000, "None"),
        std::fs::read_to_string(root().join("configs/firmware/can_seed.hex")).expect("HEX"),
    );
    let receiver = (
        bench_file("RECEIVER", 0, 0xD400, 6_000_000, "Some(Int0)"),
        assemble(PROGRAM),
    );
    bench_specs(&[sender, receiver])
}

fn covered(skip: bool) -> (harvemu_e2e::FirmwareRun, Counts) {
    let mut specs = benches();
    for s in &mut specs {
        Arc::make_mut(s).skip_idle_loops = skip;
    }
    let (run, mut counts) = run_firmware_covered(specs, bus::time::BusTime::from_secs(1), None, true);
    assert!(run.crashed.is_empty(), "{:?}", run.crashed);
    assert_eq!(run.iram(1, 0x05, 1), [10], "frames counted in R5");
    (run, counts.remove(1))
}

#[test]
fn every_instruction_is_counted_exactly_skipping_or_not() {
    let want = expected();
    for skip in [true, false] {
        let (_, got) = covered(skip);
        let diff: Vec<String> = (0..=0xFFFFu16)
            .filter(|&a| got.get(a) != want.get(a))
            .map(|a| format!("{a:04X}h: counted {:?}, expected {:?}", got.get(a), want.get(a)))
            .collect();
        assert!(diff.is_empty(), "skipping {skip}:\n{}", diff.join("\n"));
    }
}

#[test]
fn counting_changes_no_frame_and_no_state() {
    let (covered_run, _) = covered(true);
    let (plain, counts) = run_firmware_covered(benches(), bus::time::BusTime::from_secs(1), None, false);
    assert_eq!(plain.trace, covered_run.trace);
    assert_eq!(format!("{:?}", plain.states), format!("{:?}", covered_run.states));
    assert!(
        counts.iter().all(|c| c.iter().next().is_none()),
        "nothing counted when off"
    );
}

/// Timer 0 interrupts every 256 machine cycles; main counts odd and even numbers below 20,
/// waits for 50 ticks, turns interrupts off and idles.
const C_PROGRAM: &str = "#include <8051.h>

volatile unsigned char ticks;
unsigned char evens, odds;

void timer0_isr(void) __interrupt(1)
{
    ticks++;
}

void main(void)
{
    unsigned char i;

    TMOD = 0x02;
    TH0 = 0;
    ET0 = 1;
    EA = 1;
    TR0 = 1;
    for (i = 0; i < 20; i++) {
        if (i & 1)
            odds++;
        else
            evens++;
    }
    while (ticks < 50)
        ;
    EA = 0;
    for (;;)
        ;
}
";

/// Builds [`C_PROGRAM`] with SDCC into `dir` (`prog.hex` with `prog.cdb` and `prog.ihx`
/// beside it, as `--debug` and packihx leave them) with a network of that one node.
fn build_c(dir: &std::path::Path) {
    std::fs::write(dir.join("prog.c"), C_PROGRAM).unwrap();
    let out = std::process::Command::new("sdcc")
        .current_dir(dir)
        .args(["-mmcs51", "--model-small", "--debug", "prog.c"])
        .output()
        .unwrap_or_else(|e| panic!("cannot run sdcc ({e}): install the Debian package sdcc"));
    assert!(
        out.status.success(),
        "sdcc: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let packed = std::process::Command::new("packihx")
        .current_dir(dir)
        .arg("prog.ihx")
        .output()
        .unwrap_or_else(|e| panic!("cannot run packihx ({e}): install the Debian package sdcc"));
    assert!(packed.status.success());
    std::fs::write(dir.join("prog.hex"), packed.stdout).unwrap();
    std::fs::write(
        dir.join("prog.ron"),
        "Firmware(name: \"PROG\", image: \"prog.hex\", cpu: I80C51(clock_hz: 12000000), controllers: [])",
    )
    .unwrap();
    std::fs::write(
        dir.join("net.ron"),
        "Network(name: \"c program\", bitrate: 250000, nodes: [\"prog.ron\"])",
    )
    .unwrap();
}

/// One second of the C program's network with skipping on or off: its coverage, written to
/// `out`, and the lcov tracefile's text.
fn c_coverage(
    dir: &std::path::Path,
    skip: bool,
    out: &std::path::Path,
) -> (supervisor::coverage::Coverage, String) {
    use supervisor::harvester::Harvester;
    let mut h = Harvester::load(&dir.join("net.ron")).unwrap_or_else(|e| panic!("{e}"));
    for f in &mut h.firmware {
        Arc::make_mut(f).skip_idle_loops = skip;
    }
    h.coverage = true;
    let (_, coverage) = harvemu_e2e::drive(h, async |running| {
        harvemu_e2e::run_to(running, bus::time::BusTime::from_secs(1)).await;
        running.end_coverage(running.now()).await
    });
    let coverage = coverage.expect("coverage is on");
    supervisor::coverage::write(out, &coverage).expect("the reports");
    let info = std::fs::read_to_string(out.join("prog.info")).expect("the lcov tracefile");
    (coverage, info)
}

/// The line of [`C_PROGRAM`] (from 1) that holds `text`.
fn c_line(text: &str) -> usize {
    C_PROGRAM
        .lines()
        .position(|l| l.contains(text))
        .expect("the line")
        + 1
}

#[test]
fn a_c_program_s_lines_count_what_the_c_says_skipping_or_not() {
    let dir = std::env::temp_dir().join(format!("harvemu-cover-c-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    build_c(&dir);
    let (skipping, info) = c_coverage(&dir, true, &dir.join("on"));
    let (working, info_off) = c_coverage(&dir, false, &dir.join("off"));
    assert_eq!(
        skipping.images[0].counts, working.images[0].counts,
        "the same counts either way"
    );
    assert_eq!(info.replace("/on/", "/"), info_off.replace("/off/", "/"));
    let da: std::collections::BTreeMap<usize, u64> = info
        .lines()
        .filter_map(|l| {
            let (line, n) = l.strip_prefix("DA:")?.split_once(',')?;
            Some((line.parse().ok()?, n.parse().ok()?))
        })
        .collect();
    let count = |text: &str| da.get(&c_line(text)).copied();
    // Fifty ticks, then interrupts off: the handler ran fifty times.
    assert_eq!(count("ticks++;"), Some(50));
    // Twenty numbers below 20, ten odd, ten even.
    assert_eq!(count("if (i & 1)"), Some(20));
    assert_eq!(count("odds++;"), Some(10));
    assert_eq!(count("evens++;"), Some(10));
    for once in [
        "TMOD = 0x02;",
        "TH0 = 0;",
        "ET0 = 1;",
        "EA = 1;",
        "TR0 = 1;",
        "EA = 0;",
    ] {
        assert_eq!(count(once), Some(1), "{once}");
    }
    // The test `i < 20` runs 20 or 21 times, as the compiler arranges the loop.
    assert!(
        count("for (i = 0;").is_some_and(|n| (20..=21).contains(&n)),
        "{:?}",
        count("for (i = 0;")
    );
    // The handler's function once per tick, main once.
    assert!(
        info.contains("FNDA:50,timer0_isr\n") && info.contains("FNDA:1,main\n"),
        "{info}"
    );
    // The odd/even test went each way ten times.
    let branches: Vec<&str> = info
        .lines()
        .filter(|l| l.starts_with(&format!("BRDA:{},", c_line("if (i & 1)"))))
        .collect();
    assert_eq!(branches.len(), 2, "{branches:?}");
    assert!(branches.iter().all(|b| b.ends_with(",10")), "{branches:?}");
    let _ = std::fs::remove_dir_all(&dir);
}
