//! A bus at a rate whose bit time is not a whole number of nanoseconds (30 kbit/s: 33 333.3 ns)
//! keeps every frame on the bit grid over a long run: no rounding accumulates.

use bus::Frame;
use bus::bits::{self, BitRate};
use bus::engine::{Bus, BusConfig, ControllerConfig, Event};
use bus::time::{BusTime, TICKS_PER_SEC};

const RATE: u64 = 30_000;

/// `bits` bit times at 30 kbit/s in ticks, computed from the definition: bits / rate seconds.
fn ticks_of(bits: u64) -> u64 {
    let ticks = u128::from(bits) * u128::from(TICKS_PER_SEC);
    assert_eq!(ticks % u128::from(RATE), 0, "30 kbit/s has an exact bit time");
    u64::try_from(ticks / u128::from(RATE)).expect("fits")
}

#[test]
fn frames_at_30_kbits_stay_on_the_bit_grid_over_a_long_run() {
    let rate = BitRate::for_bus(30_000).expect("30 kbit/s is accepted");
    let mut b = Bus::new(BusConfig {
        bitrate: rate,
        ..BusConfig::default()
    })
    .expect("a 30 kbit/s bus");
    let tx = b.attach(ControllerConfig::named("tx"));
    let _rx = b.attach(ControllerConfig::named("rx"));
    // Where the bus is, counted in whole bits since time zero: the expectation never touches
    // the engine's arithmetic.
    let mut idle_bit = 0u64;
    let mut submit_bit = 0u64;
    let frames = 40_000u64;
    for i in 0..frames {
        let data = (i as u32).wrapping_mul(2_654_435_761).to_le_bytes();
        let f = Frame::extended(0x0CF0_0400 | (i as u32 & 0xFF), &data[..(i % 5) as usize])
            .expect("a valid frame");
        b.submit(tx, f, BusTime::from_ticks(ticks_of(submit_bit)))
            .expect("tx exists")
            .expect("queue has room");
        assert!(b.step(), "frame {i} goes out");
        let (start, end, bits_on_bus) = b
            .take_events()
            .find_map(|e| match e {
                Event::Frame { start, end, bits, .. } => Some((start, end, bits)),
                _ => None,
            })
            .expect("a frame event");
        // SOF at the submission, or when the bus is idle again after the last intermission.
        let sof_bit = submit_bit.max(idle_bit);
        // SOF .. last CRC bit stuffed (the bit-by-bit encoder), then delimiter, ACK slot and
        // delimiter, 7 EOF bits; 3 intermission bits follow.
        let stuffed = bits::encode(&f).stuffed.len() as u64;
        let end_bit = sof_bit + stuffed + 1 + 2 + 7;
        assert_eq!(start.as_ticks(), ticks_of(sof_bit), "start of frame {i}");
        assert_eq!(end.as_ticks(), ticks_of(end_bit), "end of frame {i}");
        assert_eq!(u64::from(bits_on_bus), stuffed + 13, "bits of frame {i}");
        // Printed times truncate only there: whole nanoseconds of the exact time.
        let exact_ns = u128::from(end_bit) * 1_000_000_000 / u128::from(RATE);
        assert_eq!(u128::from(end.as_nanos()), exact_ns, "nanoseconds of frame {i}");
        idle_bit = end_bit + 3;
        // Mostly back to back (queued before the bus is idle), every seventh after a gap.
        submit_bit = if i % 7 == 6 {
            idle_bit + 1 + i % 1000
        } else {
            end_bit
        };
    }
    // Minutes of bus time: a bit time rounded to 33 333 ns would have drifted by a third of a
    // nanosecond a bit, milliseconds over these millions of bits.
    assert!(idle_bit > 5_000_000, "{idle_bit} bits");
}
