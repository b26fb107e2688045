//! `harvemu inspect ID#DATA`: everything harvemu knows about one frame.

use crate::Error;
use bus::bits::{self, BitRate};
use bus::filter::{AtmelFilter, Sja1000Filter, acr_bytes_for, canidt_bytes};
use bus::{Frame, candump};
use protocol::catalogue::{self, Decoded};
use protocol::ident::AppId;
use serde_json::{Value, json};

/// Arguments of `harvemu inspect`.
#[derive(clap::Args)]
pub struct Args {
    /// The frame as candump writes it: `0601F5D0#200D0002FFBFFF00` (8 hex digits = extended,
    /// 3 = base; `123#R` for a remote frame).
    #[arg(value_name = "ID#DATA")]
    frame: String,
    /// Bit rate for the duration, in bit/s.
    #[arg(long, value_name = "BPS", default_value_t = 250_000)]
    bitrate: u32,
    /// Print one JSON object instead of text.
    #[arg(long)]
    json: bool,
}

/// Runs `harvemu inspect`.
pub fn run(args: &Args) -> crate::Result<()> {
    let frame = candump::parse_frame(&args.frame)
        .map_err(|e| Error::BadInput(format!("frame '{}': {e}", args.frame)))?;
    let rate = BitRate::new(args.bitrate)
        .ok_or_else(|| Error::BadInput(format!("bit rate {} is outside 1..=1000000 bit/s", args.bitrate)))?;
    let report = report(&frame, rate);
    let shown = if args.json {
        format!("{report}\n")
    } else {
        text(&report)
    };
    crate::output::stdout(&shown)
}

fn hex(bytes: [u8; 4]) -> String {
    bytes.iter().map(|b| format!("{b:02X}")).collect()
}

/// The whole report as JSON; the text form is written from it so the two cannot disagree.
pub fn report(frame: &Frame, rate: BitRate) -> Value {
    let encoded = bits::encode(frame);
    let total = encoded.total_bits();
    let app = AppId::from_id(frame.id()).ok();
    let name = |a: protocol::ident::Address| a.name();
    let (message, message_error) = match catalogue::decode(frame) {
        Ok(Some(d)) => (decoded(&d), Value::Null),
        Ok(None) => (Value::Null, Value::Null),
        Err(e) => (Value::Null, Value::String(e.to_string())),
    };
    json!({
        "id": if frame.is_extended() { format!("{:08X}", frame.raw_id()) } else { format!("{:03X}", frame.raw_id()) },
        "extended": frame.is_extended(),
        "remote": frame.is_remote(),
        "dlc": frame.dlc(),
        "data": frame.data().iter().map(|b| format!("{b:02X}")).collect::<String>(),
        "priority": app.map(|a| a.priority.value()),
        "priority_class": app.map(|a| a.priority.class_name()),
        "frame_type": app.map(|a| u8::from(a.frame_type)),
        "frame_type_name": app.map(|a| a.frame_type.to_string()),
        "destination": app.map(|a| a.destination.to_string()),
        "destination_name": app.and_then(|a| name(a.destination)),
        "source": app.map(|a| a.source.to_string()),
        "source_name": app.and_then(|a| name(a.source)),
        "crc": encoded.crc,
        "stuff_bits": encoded.stuff_bits,
        "bits_exact": total,
        "bits_worst_case": bits::worst_case_bits(frame),
        "bits_no_stuffing": bits::no_stuffing_bits(frame),
        "bitrate": rate.bits_per_second(),
        "duration_us": rate.duration_us(total),
        "bitstream": encoded.stuffed.to_string(),
        // Register values for a controller that is to accept exactly this identifier and RTR.
        "sja1000_acr": hex(acr_bytes_for(frame.id(), frame.is_remote())),
        "sja1000_amr": hex(Sja1000Filter::single_exact(frame.id()).amr),
        "atmel_canidt": hex(canidt_bytes(frame.id(), frame.is_remote())),
        "atmel_canidm": hex(AtmelFilter::exact(frame.id()).idm),
        "message": message,
        "message_error": message_error,
    })
}

fn decoded(d: &Decoded) -> Value {
    let fields: serde_json::Map<String, Value> = d
        .values
        .iter()
        .map(|v| {
            let f = v.field;
            (
                f.name.to_string(),
                json!({ "raw": v.raw, "value": v.physical, "unit": f.unit, "label": v.label(), "in_range": v.in_range() }),
            )
        })
        .collect();
    json!({ "name": d.message.name, "node": d.node.to_string(), "doc": d.message.doc, "fields": fields })
}

fn text(r: &Value) -> String {
    let s = |k: &str| match &r[k] {
        Value::String(s) => s.clone(),
        Value::Null => "-".to_string(),
        other => other.to_string(),
    };
    let mut out = String::new();
    let mut line = |label: &str, value: String| out += &format!("{label:<13}{value}\n");
    let kind = if r["extended"] == true { "extended" } else { "base" };
    let (rtr, data) = if r["remote"] == true {
        (", remote", "R".to_string())
    } else {
        ("", s("data"))
    };
    line(
        "frame",
        format!("{}#{data} ({kind}{rtr}, DLC {})", s("id"), s("dlc")),
    );
    if r["priority"].is_null() {
        line("", "(a base identifier: not a harvester identifier)".into());
    } else {
        line("priority", format!("{} ({})", s("priority"), s("priority_class")));
        line(
            "frame type",
            format!(
                "{:02} ({})",
                r["frame_type"].as_u64().unwrap_or(0),
                s("frame_type_name")
            ),
        );
        line(
            "destination",
            format!("{} ({})", s("destination"), s("destination_name")),
        );
        line("source", format!("{} ({})", s("source"), s("source_name")));
    }
    match &r["message"] {
        Value::Object(m) => {
            let text = |k: &str| m[k].as_str().unwrap_or("").to_string();
            line(
                "message",
                format!("{} (node {}): {}", text("name"), text("node"), text("doc")),
            );
            for (name, f) in m["fields"].as_object().into_iter().flatten() {
                let value = f["value"].as_f64().unwrap_or(f64::NAN);
                let unit = f["unit"].as_str().unwrap_or("");
                let label = f["label"].as_str().map(|l| format!(" ({l})")).unwrap_or_default();
                let range = if f["in_range"] == false {
                    "  OUT OF RANGE"
                } else {
                    ""
                };
                line("", format!("{name:<20} {value} {unit}{label}{range}"));
            }
        }
        _ => match r["message_error"].as_str() {
            Some(e) => line("message", format!("malformed: {e}")),
            None => line("message", "not in the catalogue".into()),
        },
    }
    line("CRC-15", format!("0x{:04X}", r["crc"].as_u64().unwrap_or(0)));
    line("stuff bits", s("stuff_bits"));
    line(
        "bits",
        format!(
            "{} exact, {} worst case, {} without stuffing (intermission included)",
            s("bits_exact"),
            s("bits_worst_case"),
            s("bits_no_stuffing")
        ),
    );
    line(
        "duration",
        format!(
            "{:.3} us at {} bit/s",
            r["duration_us"].as_f64().unwrap_or(0.0),
            s("bitrate")
        ),
    );
    line("bitstream", format!("{} (SOF..CRC, stuffed)", s("bitstream")));
    line(
        "SJA1000",
        format!(
            "ACR {} AMR {} (single filter for this identifier and RTR)",
            s("sja1000_acr"),
            s("sja1000_amr")
        ),
    );
    line(
        "Atmel",
        format!(
            "CANIDT {} CANIDM {} (left-aligned, as the seed)",
            s("atmel_canidt"),
            s("atmel_canidm")
        ),
    );
    out
}
