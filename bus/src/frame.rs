//! Classic CAN frames and their arbitration order.

use crate::Error;
use embedded_can::{ExtendedId, Id, StandardId};

/// A classic CAN 2.0 data or remote frame.
///
/// Invariants, upheld by every constructor: `dlc <= 8`; a data frame's DLC is its payload length;
/// bytes past the payload are zero (so derived equality and hashing see only what is on the wire).
#[derive(Clone, Copy, PartialEq, Eq, Hash)]
pub struct Frame {
    id: Id,
    remote: bool,
    dlc: u8,
    data: [u8; 8],
}

impl Frame {
    /// A data frame carrying `data` (0 to 8 bytes).
    pub fn new_data(id: impl Into<Id>, data: &[u8]) -> Result<Frame, Error> {
        if data.len() > 8 {
            return Err(Error::TooMuchData(data.len()));
        }
        let mut buf = [0u8; 8];
        buf[..data.len()].copy_from_slice(data);
        Ok(Frame {
            id: id.into(),
            remote: false,
            dlc: data.len() as u8,
            data: buf,
        })
    }

    /// A remote frame asking for `dlc` bytes (0 to 8); it carries no data on the wire.
    pub fn new_remote(id: impl Into<Id>, dlc: usize) -> Result<Frame, Error> {
        if dlc > 8 {
            return Err(Error::BadDlc(dlc));
        }
        Ok(Frame {
            id: id.into(),
            remote: true,
            dlc: dlc as u8,
            data: [0; 8],
        })
    }

    /// A data frame with an extended identifier given as a raw 29-bit number.
    pub fn extended(raw_id: u32, data: &[u8]) -> Result<Frame, Error> {
        Frame::new_data(extended_id(raw_id)?, data)
    }

    /// A data frame with a base identifier given as a raw 11-bit number.
    pub fn base(raw_id: u16, data: &[u8]) -> Result<Frame, Error> {
        Frame::new_data(standard_id(raw_id)?, data)
    }

    /// The identifier.
    pub fn id(&self) -> Id {
        self.id
    }

    /// The identifier as a number (11 or 29 significant bits).
    pub fn raw_id(&self) -> u32 {
        match self.id {
            Id::Standard(id) => u32::from(id.as_raw()),
            Id::Extended(id) => id.as_raw(),
        }
    }

    /// True for a 29-bit identifier.
    pub fn is_extended(&self) -> bool {
        matches!(self.id, Id::Extended(_))
    }

    /// True for a remote (RTR) frame.
    pub fn is_remote(&self) -> bool {
        self.remote
    }

    /// The data length code, 0 to 8.
    pub fn dlc(&self) -> u8 {
        self.dlc
    }

    /// The payload: empty for a remote frame.
    pub fn data(&self) -> &[u8] {
        if self.remote {
            &[]
        } else {
            &self.data[..usize::from(self.dlc)]
        }
    }

    /// The key by which the bus arbitrates this frame: lower wins.
    pub fn arbitration(&self) -> ArbitrationKey {
        ArbitrationKey::of(self.id, self.remote)
    }
}

impl Frame {
    /// Appends the frame in candump's `ID#DATA` notation to `out`: the identifier in upper-case
    /// hex (3 digits base, 8 extended), `#`, then the data bytes in upper-case hex, or `R` and a
    /// non-zero DLC for a remote frame. [`crate::candump`] reads and writes this notation.
    pub fn write_text(&self, out: &mut String) {
        use core::fmt::Write;
        // Writing to a String cannot fail.
        let _ = match self.id {
            Id::Standard(id) => write!(out, "{:03X}#", id.as_raw()),
            Id::Extended(id) => write!(out, "{:08X}#", id.as_raw()),
        };
        if self.remote {
            out.push('R');
            if self.dlc() > 0 {
                let _ = write!(out, "{}", self.dlc());
            }
        } else {
            for b in self.data() {
                let _ = write!(out, "{b:02X}");
            }
        }
    }
}

impl core::fmt::Debug for Frame {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        let mut text = String::with_capacity(26);
        self.write_text(&mut text);
        write!(f, "Frame({text})")
    }
}

impl embedded_can::Frame for Frame {
    fn new(id: impl Into<Id>, data: &[u8]) -> Option<Self> {
        Frame::new_data(id, data).ok()
    }
    fn new_remote(id: impl Into<Id>, dlc: usize) -> Option<Self> {
        Frame::new_remote(id, dlc).ok()
    }
    fn is_extended(&self) -> bool {
        Frame::is_extended(self)
    }
    fn is_remote_frame(&self) -> bool {
        self.remote
    }
    fn id(&self) -> Id {
        self.id
    }
    fn dlc(&self) -> usize {
        usize::from(self.dlc)
    }
    fn data(&self) -> &[u8] {
        Frame::data(self)
    }
}

/// Checked construction of an 11-bit identifier.
pub fn standard_id(raw: u16) -> Result<StandardId, Error> {
    StandardId::new(raw).ok_or(Error::IdOutOfRange {
        raw: u32::from(raw),
        bits: 11,
    })
}

/// Checked construction of a 29-bit identifier.
pub fn extended_id(raw: u32) -> Result<ExtendedId, Error> {
    ExtendedId::new(raw).ok_or(Error::IdOutOfRange { raw, bits: 29 })
}

/// The arbitration field read as one number, MSB first, so that the numeric order is the bus
/// order.
///
/// Layout (32 bits): ID28..18 (or the base ID10..0), then the bit after them (SRR, recessive, in
/// an extended frame; RTR in a base frame), then IDE, then ID17..0, then RTR of an extended
/// frame. A base frame has nothing after IDE that takes part in arbitration: its IDE bit is
/// dominant, so it has already won or lost against any extended frame by then, and two base
/// frames with the same ID and RTR cannot be told apart by arbitration at all.
#[derive(Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Debug)]
pub struct ArbitrationKey(u32);

impl ArbitrationKey {
    /// The key of a frame with this identifier and RTR bit.
    pub fn of(id: Id, remote: bool) -> ArbitrationKey {
        let rtr = u32::from(remote);
        ArbitrationKey(match id {
            Id::Standard(id) => (u32::from(id.as_raw()) << 21) | (rtr << 20),
            Id::Extended(id) => {
                let raw = id.as_raw();
                ((raw >> 18) << 21) | (1 << 20) | (1 << 19) | ((raw & 0x3FFFF) << 1) | rtr
            }
        })
    }

    /// The key as a number.
    pub fn raw(self) -> u32 {
        self.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn key(f: Frame) -> ArbitrationKey {
        f.arbitration()
    }

    #[test]
    fn constructors_check_sizes() {
        assert_eq!(Frame::base(0x123, &[0; 9]), Err(Error::TooMuchData(9)));
        assert_eq!(
            Frame::new_remote(standard_id(1).unwrap(), 9),
            Err(Error::BadDlc(9))
        );
        assert!(matches!(
            Frame::base(0x800, &[]),
            Err(Error::IdOutOfRange { bits: 11, .. })
        ));
        assert!(matches!(
            Frame::extended(0x2000_0000, &[]),
            Err(Error::IdOutOfRange { bits: 29, .. })
        ));
        let f = Frame::extended(0x0601F5D0, &[1, 2, 3]).unwrap();
        assert_eq!((f.raw_id(), f.dlc(), f.data()), (0x0601F5D0, 3, &[1u8, 2, 3][..]));
        let r = Frame::new_remote(standard_id(0x7FF).unwrap(), 4).unwrap();
        assert_eq!((r.dlc(), r.data().len(), r.is_remote()), (4, 0, true));
    }

    #[test]
    fn lower_identifier_wins() {
        let a = Frame::extended(0x0300A0F5, &[]).unwrap();
        let b = Frame::extended(0x0601F5D0, &[]).unwrap();
        assert!(key(a) < key(b));
        assert!(key(Frame::base(0x100, &[]).unwrap()) < key(Frame::base(0x101, &[]).unwrap()));
    }

    #[test]
    fn base_beats_extended_with_same_high_bits() {
        // 0x123 << 18 has the same 11 high bits as base 0x123.
        let ext = Frame::extended(0x123 << 18, &[]).unwrap();
        let base_data = Frame::base(0x123, &[]).unwrap();
        let base_remote = Frame::new_remote(standard_id(0x123).unwrap(), 0).unwrap();
        assert!(key(base_data) < key(ext), "RTR d beats SRR r");
        assert!(key(base_remote) < key(ext), "IDE d beats IDE r");
        // But a lower extended high part still beats a higher base id.
        let ext_low = Frame::extended(0x122 << 18 | 0x3FFFF, &[]).unwrap();
        assert!(key(ext_low) < key(base_data));
    }

    #[test]
    fn data_beats_remote_with_same_identifier() {
        let d = Frame::extended(0x0300A0F5, &[]).unwrap();
        let r = Frame::new_remote(extended_id(0x0300A0F5).unwrap(), 0).unwrap();
        assert!(key(d) < key(r));
        let d = Frame::base(0x7FF, &[]).unwrap();
        let r = Frame::new_remote(standard_id(0x7FF).unwrap(), 0).unwrap();
        assert!(key(d) < key(r));
    }
}
