//! The core's state, its memory spaces and the public stepping API.

mod access;
mod adc;
pub(crate) mod cc03;
mod interrupts;
mod ops;
mod sfrs;
mod timer2;
mod timers;
mod types;
mod watch;

pub(crate) use sfrs::*;
pub use types::{RunEnd, Snapshot, Step, XAccess};
pub use watch::{ADC_LEAD, Watched};

use crate::{Cover, Error, Image, Variant, Xdata};
use std::sync::Arc;

/// Transmission in progress: what still has to pass before TI is set.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Tx {
    Idle,
    Cycles(u32),
    Overflows(u32),
}

/// An 80C51/8052 core. Cloning is cheap: the code memory is shared.
#[derive(Debug, Clone)]
pub struct Cpu {
    pub(crate) code: Arc<[u8; 0x10000]>,
    pub(crate) iram: [u8; 256],
    pub(crate) sfr: [u8; 128],
    pub(crate) pc: u16,
    /// PC of the instruction being executed, for fault reports.
    pub(crate) op_pc: u16,
    pub(crate) cycles: u64,
    pub(crate) ram_top: u8,
    /// External levels driven on the port pins (a pin reads latch AND level).
    pub(crate) ext: [u8; 4],
    pub(crate) in_service: u8,
    /// Set by RETI and writes to IE/IP: the next instruction runs before any interrupt.
    pub(crate) inhibit: bool,
    pub(crate) tx: Tx,
    pub(crate) serial_out: Vec<u8>,
    /// Timers and the serial port are up to date to this cycle.
    pub(crate) synced: u64,
    /// The cycle of the next timer overflow or serial event (u64::MAX: none coming).
    pub(crate) next_event: u64,
    /// The cycle at which the executing instruction reads and writes.
    pub(crate) effect_at: u64,
    pub(crate) xaccess: Option<XAccess>,
    pub(crate) fault: Option<u16>,
    pub(crate) entry_cycles: u8,
    pub(crate) skipped: u64,
    /// SFRs the core implements for its variant; the others go to [`Xdata::sfr_read`] and
    /// [`Xdata::sfr_write`].
    pub(crate) own: &'static [bool; 128],
    /// SFRs brought up to date with the timers before an access.
    pub(crate) timed: &'static [bool; 128],
    /// On-chip XRAM (AT89C51CC03), empty otherwise; its presence marks that variant.
    pub(crate) xram: Arc<Vec<u8>>,
    /// Outside interrupt requests ([`Xdata::irq`]) as last read.
    pub(crate) ext_irq: u8,
    /// The last poll for interrupts took none, and nothing it reads has changed since: the
    /// flags and enables (TCON, SCON, T2CON, ADCON, IE, IP and the AT89C51CC03's IEN1, IPL1,
    /// IPH0, IPH1), the outside requests, the handlers in service. Whatever changes one of
    /// them clears it, so the next poll looks again; the others cost the run loop one test.
    pub(crate) irq_quiet: bool,
    /// The executing instruction reached an SFR through the hook.
    pub(crate) hooked: bool,
    /// Cycle at which the ADC conversion under way ends (u64::MAX: none).
    pub(crate) adc_end: u64,
    pub(crate) analog: [u16; 8],
    /// Each channel's multiplexer: the port and bit whose latch selects `analog_high`.
    pub(crate) mux: [Option<(u8, u8)>; 8],
    pub(crate) analog_high: [u16; 8],
    /// What the caller drives and reads (see [`watch`]).
    pub(crate) watched: Watched,
    /// The first machine cycle at which the watched inputs no longer hold (u64::MAX: always).
    pub(crate) stale_from: u64,
    /// The last instruction changed a watched latch bit.
    pub(crate) output_changed: bool,
    pub(crate) input_reads: u64,
    pub(crate) time_reads: u64,
    /// [`Cpu::run`] stops when an instruction leaves the PC here (u32::MAX: never).
    pub(crate) stop_pc: u32,
    /// The last instruction reached the outside (MOVX, a hooked SFR) or changed the clock or a
    /// watched latch: [`Cpu::run`] looks at what it must stop for.
    pub(crate) attention: bool,
    /// The cycle of the last timer, serial, ADC or watchdog event that took effect.
    pub(crate) last_event: u64,
    /// The cycle at which the caller last set the watched inputs.
    pub(crate) served_at: u64,
    /// Cycle at which the watchdog resets the core (u64::MAX: not running).
    pub(crate) wdt_deadline: u64,
    /// The last WDTRST write was 1Eh.
    pub(crate) wdt_armed: bool,
    pub(crate) wdt_resets: u64,
    /// (cycles, oscillator clocks) when X2 last changed.
    pub(crate) clock_base: (u64, u64),
    pub(crate) clock_changed: bool,
}

impl Cpu {
    /// A core at reset running `image` (code beyond the image reads FFh).
    pub fn new(variant: Variant, image: &Image) -> Cpu {
        let mut code = Box::new([0xFF; 0x10000]);
        let n = image.code.len().min(0x10000);
        code[..n].copy_from_slice(&image.code[..n]);
        let mut cpu = Cpu {
            code: Arc::from(code),
            iram: [0; 256],
            sfr: [0; 128],
            pc: 0,
            op_pc: 0,
            cycles: 0,
            ram_top: if variant == Variant::I8051 { 0x7F } else { 0xFF },
            ext: [0xFF; 4],
            in_service: 0,
            inhibit: false,
            tx: Tx::Idle,
            serial_out: Vec::new(),
            synced: 0,
            next_event: u64::MAX,
            effect_at: 0,
            xaccess: None,
            fault: None,
            entry_cycles: 2,
            skipped: 0,
            own: if variant == Variant::At89c51cc03 {
                &cc03::CC03_OWN
            } else {
                &WRITABLE
            },
            timed: if variant == Variant::At89c51cc03 {
                &cc03::CC03_TIMED
            } else {
                &TIMED
            },
            // Shared by the copies a caller keeps, copied on the first write after one is taken.
            xram: Arc::new(if variant == Variant::At89c51cc03 {
                vec![0; cc03::XRAM_BYTES]
            } else {
                Vec::new()
            }),
            ext_irq: 0,
            irq_quiet: false,
            hooked: false,
            adc_end: u64::MAX,
            analog: [0; 8],
            mux: [None; 8],
            analog_high: [0; 8],
            watched: Watched::default(),
            stale_from: u64::MAX,
            output_changed: false,
            input_reads: 0,
            time_reads: 0,
            stop_pc: u32::MAX,
            attention: false,
            last_event: 0,
            served_at: 0,
            wdt_deadline: u64::MAX,
            wdt_armed: false,
            wdt_resets: 0,
            clock_base: (0, 0),
            clock_changed: false,
        };
        cpu.reset();
        cpu
    }

    /// Hardware reset: SP 07h, ports FFh, PC and other SFRs 0 (AUXR on the AT89C51CC03: see
    /// its section in the crate docs), no interrupt in service, a fault cleared, no ADC
    /// conversion, the watchdog stopped; internal RAM and XRAM are kept (as on a warm reset),
    /// the cycle count too.
    pub fn reset(&mut self) {
        self.clock_base = (self.cycles, self.clocks());
        self.sfr = [0; 128];
        for p in [P0, P1, P2, P3] {
            self.sfr[(p - 0x80) as usize] = 0xFF;
        }
        self.sfr[(SP - 0x80) as usize] = 0x07;
        self.pc = 0;
        self.in_service = 0;
        self.inhibit = false;
        self.irq_quiet = false;
        self.tx = Tx::Idle;
        self.fault = None;
        if self.cc03() {
            self.reset_cc03();
        }
        self.synced = self.cycles;
        self.sync_ext_ints();
        self.plan();
    }

    /// Sets the program counter (an entry point other than 0000h).
    pub fn set_pc(&mut self, pc: u16) {
        self.pc = pc;
    }

    /// Machine cycles of the hardware call that enters an interrupt: 2 by the Intel manual
    /// (the default); s51 (uCsim 0.6) takes 1, and tests that compare with it set 1.
    pub fn set_interrupt_entry_cycles(&mut self, cycles: u8) {
        self.entry_cycles = cycles;
    }

    /// Program counter.
    pub fn pc(&self) -> u16 {
        self.pc
    }

    /// Machine cycles since the core was made.
    pub fn cycles(&self) -> u64 {
        self.cycles
    }

    /// Machine cycles that [`Cpu::run`] passed in closed form in DJNZ delay loops (included
    /// in [`Cpu::cycles`]).
    pub fn skipped_cycles(&self) -> u64 {
        self.skipped
    }

    /// Internal RAM 00h–FFh (the upper half is zero on the 80C51).
    pub fn iram(&self) -> [u8; 256] {
        self.iram
    }

    /// SFRs 80h–FFh at index `addr - 80h`: ports show their latches, PSW its parity bit,
    /// SBUF the receive buffer, unimplemented addresses 00h.
    pub fn sfr(&self) -> [u8; 128] {
        let mut s = self.sfr;
        s[(PSW - 0x80) as usize] = self.psw();
        s
    }

    /// The state that decides what happens next; see [`Snapshot`].
    pub fn snapshot(&self) -> Snapshot {
        Snapshot {
            pc: self.pc,
            iram: self.iram,
            sfr: self.sfr(),
            in_service: self.in_service,
            xram: self.xram.to_vec(),
            analog: self.analog,
        }
    }

    /// Bytes written to SBUF since the last call.
    pub fn take_serial(&mut self) -> Vec<u8> {
        std::mem::take(&mut self.serial_out)
    }

    /// Drives external pin `bit` of port `port` (0–3) to `level`. A pin reads as its latch AND
    /// this level. Falling edges on P3.2/P3.3 (INT0/INT1, edge mode) and P3.4/P3.5 (T0/T1) count,
    /// on the AT89C51CC03 also P1.0/P1.1 (T2/T2EX). Out-of-range ports or bits are ignored.
    pub fn set_pin(&mut self, port: u8, bit: u8, level: bool) {
        if port > 3 || bit > 7 {
            return;
        }
        self.sync(self.cycles);
        let before = self.pins(port as usize);
        let p = &mut self.ext[port as usize];
        *p = if level { *p | 1 << bit } else { *p & !(1 << bit) };
        if port == 3 {
            self.p3_changed(before);
        } else if port == 1 && self.cc03() {
            self.p1_changed(before);
        }
        self.plan();
    }

    /// Executes one instruction, or enters one interrupt.
    pub fn step(&mut self, x: &mut dyn Xdata) -> Result<Step, Error> {
        self.step_covered(x, &mut ())
    }

    /// [`Cpu::step`], telling `cover` of the instruction it executes.
    pub fn step_covered<C: Cover>(&mut self, x: &mut dyn Xdata, cover: &mut C) -> Result<Step, Error> {
        if let Some(pc) = self.fault {
            return Err(Error::Stopped { pc });
        }
        self.xaccess = None;
        self.set_ext_irq(x.irq());
        if self.watchdog_due() {
            self.watchdog_reset();
        }
        if let Some(vector) = self.poll_interrupt()? {
            self.sync(self.cycles);
            return Ok(Step {
                cycles: self.entry_cycles,
                xdata: None,
                interrupt: Some(vector),
            });
        }
        // One instruction: no delay loop is passed.
        let cycles = self.execute(x, 0, cover)?;
        self.sync(self.cycles);
        Ok(Step {
            cycles,
            xdata: self.xaccess,
            interrupt: None,
        })
    }

    /// Runs while the cycle count is below `until`, skipping DJNZ delay loops in closed form,
    /// and returns early right after a MOVX write.
    pub fn run(&mut self, x: &mut dyn Xdata, until: u64) -> Result<RunEnd, Error> {
        self.run_covered(x, until, &mut ())
    }

    /// [`Cpu::run`], telling `cover` of every instruction it executes, those of a delay loop
    /// passed in closed form included ([`Cover::looped`]).
    pub fn run_covered<C: Cover>(
        &mut self,
        x: &mut dyn Xdata,
        until: u64,
        cover: &mut C,
    ) -> Result<RunEnd, Error> {
        if let Some(pc) = self.fault {
            return Err(Error::Stopped { pc });
        }
        self.set_ext_irq(x.irq());
        // Set only with `attention`, and taken by `attend`.
        self.xaccess = None;
        self.hooked = false;
        while self.cycles < until {
            if self.watchdog_due() {
                self.watchdog_reset();
                return Ok(RunEnd::WatchdogReset);
            }
            if self.cycles >= self.stale_from && self.inputs_due() {
                self.sync(self.cycles);
                return Ok(RunEnd::InputsDue);
            }
            if self.poll_interrupt()?.is_some() {
                continue;
            }
            if self.execute(x, until, cover)? == 0 {
                // A delay loop passed in closed form.
                continue;
            }
            if self.attention
                && let Some(end) = self.attend(x)
            {
                self.sync(self.cycles);
                return Ok(end);
            }
            if u32::from(self.pc) == self.stop_pc {
                self.sync(self.cycles);
                return Ok(RunEnd::AtPc);
            }
        }
        self.sync(self.cycles);
        Ok(RunEnd::Reached)
    }

    /// What [`Cpu::run`] stops for after an instruction that asked for attention (it reached
    /// the outside, or changed the clock or a watched latch), if anything.
    #[cold]
    fn attend(&mut self, x: &mut dyn Xdata) -> Option<RunEnd> {
        self.attention = false;
        let xaccess = self.xaccess.take();
        let hooked = std::mem::take(&mut self.hooked);
        if let Some(end) = self.watch_stop() {
            return Some(end);
        }
        if let Some(XAccess::Write { addr, value }) = xaccess {
            return Some(RunEnd::XdataWrite { addr, value });
        }
        if (xaccess.is_some() || hooked) && x.wants_stop() {
            return Some(RunEnd::Peripheral);
        }
        if self.clock_changed {
            self.clock_changed = false;
            return Some(RunEnd::ClockChanged);
        }
        None
    }

    /// A fault: the core stops at `pc`.
    pub(crate) fn fail(&mut self, e: Error) -> Error {
        self.fault = Some(self.op_pc);
        e
    }

    pub(crate) fn psw(&self) -> u8 {
        let acc = self.sfr[(ACC - 0x80) as usize];
        (self.sfr[(PSW - 0x80) as usize] & 0xFE) | (acc.count_ones() & 1) as u8
    }

    /// Pin levels of port `n`: latch AND external level.
    pub(crate) fn pins(&self, n: usize) -> u8 {
        self.sfr[0x10 * n] & self.ext[n]
    }

    /// Reads an SFR; `pins` selects the port pins rather than the latches. An SFR the core
    /// does not implement goes to the hook.
    pub(crate) fn read_sfr(&mut self, x: &mut dyn Xdata, addr: u8, pins: bool) -> u8 {
        let i = (addr - 0x80) as usize;
        if !self.own[i] {
            x.sfr_clock(self.clocks_at(self.effect_at));
            let v = x.sfr_read(addr);
            self.hooked = true;
            self.attention = true;
            self.set_ext_irq(x.irq());
            return v.unwrap_or(0);
        }
        if self.timed[i] {
            self.sync(self.effect_at);
            if matches!(addr, TL0 | TH0 | TL1 | TH1 | timer2::TL2 | timer2::TH2) {
                self.time_reads += 1;
            }
        }
        match addr {
            P0 | P1 | P2 | P3 if pins => {
                let port = ((addr - 0x80) >> 4) as usize;
                if self.watched.pins[port] != 0 {
                    self.input_reads += 1;
                }
                self.pins(port)
            }
            PSW => self.psw(),
            _ => self.sfr[(addr - 0x80) as usize],
        }
    }

    pub(crate) fn write_sfr(&mut self, x: &mut dyn Xdata, addr: u8, v: u8) {
        let i = (addr - 0x80) as usize;
        if !self.own[i] {
            x.sfr_clock(self.clocks_at(self.effect_at));
            x.sfr_write(addr, v);
            self.hooked = true;
            self.attention = true;
            self.set_ext_irq(x.irq());
            return;
        }
        if !self.timed[i] {
            if addr & 0xCF == 0x80 {
                self.port_written(((addr - 0x80) >> 4) as usize, self.sfr[i], v);
            }
            self.sfr[i] = v;
            if cc03::is_interrupt_register(addr) {
                self.inhibit = true;
                self.irq_quiet = false;
            }
            return;
        }
        self.irq_quiet = false;
        self.sync(self.effect_at);
        match addr {
            SBUF => self.transmit(v),
            P3 => {
                let before = self.pins(3);
                self.port_written(3, self.sfr[i], v);
                self.sfr[i] = v;
                self.p3_changed(before);
            }
            TCON => {
                self.sfr[i] = v;
                self.sync_ext_ints();
            }
            _ if self.cc03() => self.write_cc03(addr, v),
            _ => self.sfr[i] = v,
        }
        self.plan();
    }
}
