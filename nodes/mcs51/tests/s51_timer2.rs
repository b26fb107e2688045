//! Timer 2 of the AT89C51CC03 against s51's 8052 (uCsim): auto-reload with interrupts and
//! capture mode (a plain 16-bit count) polled, compared on RAM, SFRs, timer 2's SFRs and cycles.

mod support;

use mcs51::Variant;
use support::{assemble, compare, run_ours, run_s51};

const T2_SFRS: [(u8, &str); 5] = [
    (0xC8, "T2CON"),
    (0xCA, "RCAP2L"),
    (0xCB, "RCAP2H"),
    (0xCC, "TL2"),
    (0xCD, "TH2"),
];

fn check_timer2(src: &str) {
    let p = assemble(src);
    let ours = run_ours(&p, Variant::At89c51cc03, 5_000_000, &[]);
    let theirs = run_s51(&p, Variant::At89c51cc03, "");
    compare(&ours, &theirs, src);
    for (addr, name) in T2_SFRS {
        let i = addr as usize - 0x80;
        assert_eq!(ours.sfr[i], theirs.sfr[i], "{name} differs from s51\n{src}");
    }
}

/// Auto-reload from RCAP2 = FFC0h, 64 cycles a period; the handler clears TF2 and counts.
#[test]
fn timer2_auto_reload_interrupts() {
    check_timer2(
        "\t.org 0
\tljmp start
\t.org 2Bh
\tclr 0CFh
\tinc 30h
\tmov 31h,0CCh
\treti
\t.org 40h
start:\tmov 0CAh,#0C0h
\tmov 0CBh,#0FFh
\tmov 0CCh,#0F0h
\tmov 0CDh,#0FFh
\tmov ie,#0A0h
\tsetb 0CAh
loop:\tinc 32h
\tmov a,30h
\tcjne a,#12,loop
\tclr ea
\tclr 0CAh
done:\tsjmp done
",
    );
}

/// Capture mode without EXEN2: TH2:TL2 wraps from FFFFh to 0000h and sets TF2, RCAP2 unchanged.
#[test]
fn timer2_capture_mode_wraps_and_sets_tf2() {
    check_timer2(
        "\t.org 0
\tmov 0CAh,#12h
\tmov 0CBh,#34h
\tmov 0CCh,#0E0h
\tmov 0CDh,#0FFh
\tmov 0C8h,#05h
w:\tinc 30h
\tjnb 0CFh,w
\tmov 31h,0CCh
\tmov 32h,0CDh
\tclr 0CAh
done:\tsjmp done
",
    );
}
