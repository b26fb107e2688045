//! The 80C51's special function registers: their addresses, names, and which the core
//! implements and keeps in step with the timers.

/// Defines each SFR address constant and [`SFRS`], the list of (address, name) the
/// disassembler prints, from one list: a name is spelled once.
macro_rules! sfrs {
    ($($name:ident = $addr:literal,)*) => {
        $(pub(crate) const $name: u8 = $addr;)*
        /// The 80C51's SFRs, the ones the core implements on every variant, by address and name.
        pub(crate) const SFRS: &[(u8, &str)] = &[$(($name, stringify!($name)),)*];
    };
}

// SFR addresses (Intel MCS-51 User's Manual, table of special function registers).
sfrs! {
    P0 = 0x80,
    SP = 0x81,
    DPL = 0x82,
    DPH = 0x83,
    PCON = 0x87,
    TCON = 0x88,
    TMOD = 0x89,
    TL0 = 0x8A,
    TL1 = 0x8B,
    TH0 = 0x8C,
    TH1 = 0x8D,
    P1 = 0x90,
    SCON = 0x98,
    SBUF = 0x99,
    P2 = 0xA0,
    IE = 0xA8,
    P3 = 0xB0,
    IP = 0xB8,
    PSW = 0xD0,
    ACC = 0xE0,
    B = 0xF0,
}

/// Whether each SFR address 80h–FFh is implemented (writes elsewhere are ignored).
pub(crate) const WRITABLE: [bool; 128] = {
    let mut t = [false; 128];
    let mut i = 0;
    while i < SFRS.len() {
        t[(SFRS[i].0 - 0x80) as usize] = true;
        i += 1;
    }
    t
};

/// SFRs whose value depends on or changes the timers or the serial port: they are brought up
/// to date before an access.
pub(crate) const TIMED: [bool; 128] = {
    let mut t = [false; 128];
    let timed = [TCON, TMOD, TL0, TL1, TH0, TH1, SCON, SBUF, P3];
    let mut i = 0;
    while i < timed.len() {
        t[(timed[i] - 0x80) as usize] = true;
        i += 1;
    }
    t
};
