//! Reading back the TensorBoard event files training writes, to check
//! what a run logged. A file is a sequence of records: the payload length
//! (u64, little endian), the masked CRC-32C of those 8 bytes, the payload,
//! and the masked CRC-32C of the payload; each payload is an `Event`
//! protocol buffer whose few fields are decoded here.

use std::path::Path;

/// TensorBoard's CRC mask constant.
const MASK_DELTA: u32 = 0xa282_ead8;

/// The masked CRC-32C that TensorBoard's records carry.
fn masked_crc(bytes: &[u8]) -> u32 {
    crc32c::crc32c(bytes)
        .rotate_right(15)
        .wrapping_add(MASK_DELTA)
}

/// One value of an event read back.
#[derive(Debug, Clone, PartialEq)]
pub enum EventValue {
    /// The file version of the first event.
    FileVersion(String),
    /// A scalar with its tag.
    Scalar(String, f32),
    /// An image with its tag, size (width, height) and PNG bytes.
    Image(String, (u32, u32), Vec<u8>),
    /// A `SessionLog` START: a run resumed at this event's step.
    SessionStart,
}

/// An event read back: its step and value.
#[derive(Debug, Clone, PartialEq)]
pub struct Event {
    /// The step it was logged at.
    pub step: u64,
    /// What it holds.
    pub value: EventValue,
}

/// A protobuf reader over the few wire types events use.
struct Reader<'a> {
    bytes: &'a [u8],
}

/// One field: its number and its raw value (varint, 32-bit, or bytes; the
/// only 64-bit field, the wall time, is skipped).
enum Field<'a> {
    Varint(u32, u64),
    Fixed32(u32, [u8; 4]),
    Fixed64,
    Bytes(u32, &'a [u8]),
}

impl<'a> Reader<'a> {
    fn varint(&mut self) -> Option<u64> {
        let mut value = 0u64;
        for shift in (0..64).step_by(7) {
            let (&byte, rest) = self.bytes.split_first()?;
            self.bytes = rest;
            value |= u64::from(byte & 0x7f) << shift;
            if byte < 0x80 {
                return Some(value);
            }
        }
        None
    }

    fn take(&mut self, n: usize) -> Option<&'a [u8]> {
        if self.bytes.len() < n {
            return None;
        }
        let (head, rest) = self.bytes.split_at(n);
        self.bytes = rest;
        Some(head)
    }

    fn field(&mut self) -> Option<Field<'a>> {
        let key = self.varint()?;
        let number = u32::try_from(key >> 3).ok()?;
        Some(match key & 7 {
            0 => Field::Varint(number, self.varint()?),
            1 => {
                self.take(8)?;
                Field::Fixed64
            }
            2 => {
                let n = usize::try_from(self.varint()?).ok()?;
                Field::Bytes(number, self.take(n)?)
            }
            5 => Field::Fixed32(number, self.take(4)?.try_into().ok()?),
            _ => return None,
        })
    }

    /// Every field, or `None` if the bytes are not a message.
    fn fields(bytes: &'a [u8]) -> Option<Vec<Field<'a>>> {
        let mut reader = Reader { bytes };
        let mut fields = Vec::new();
        while !reader.bytes.is_empty() {
            fields.push(reader.field()?);
        }
        Some(fields)
    }
}

/// The value of a `Summary.Value` message.
fn summary_value(bytes: &[u8]) -> Option<EventValue> {
    let mut tag = String::new();
    let mut value = None;
    for field in Reader::fields(bytes)? {
        match field {
            Field::Bytes(1, t) => tag = String::from_utf8(t.to_vec()).ok()?,
            Field::Fixed32(2, v) => value = Some((f32::from_le_bytes(v), None)),
            Field::Bytes(4, image) => {
                let (mut w, mut h, mut png) = (0, 0, Vec::new());
                for f in Reader::fields(image)? {
                    match f {
                        Field::Varint(1, v) => h = u32::try_from(v).ok()?,
                        Field::Varint(2, v) => w = u32::try_from(v).ok()?,
                        Field::Bytes(4, b) => png = b.to_vec(),
                        _ => {}
                    }
                }
                value = Some((0.0, Some(((w, h), png))));
            }
            _ => {}
        }
    }
    Some(match value? {
        (_, Some((size, png))) => EventValue::Image(tag, size, png),
        (v, None) => EventValue::Scalar(tag, v),
    })
}

/// The events of one event payload (a summary may hold several values).
fn decode_event(payload: &[u8]) -> Option<Vec<Event>> {
    let mut step = 0;
    let mut values = Vec::new();
    for field in Reader::fields(payload)? {
        match field {
            Field::Varint(2, s) => step = s,
            Field::Bytes(3, v) => {
                values.push(EventValue::FileVersion(String::from_utf8(v.to_vec()).ok()?))
            }
            Field::Bytes(7, session_log) => {
                let start = Reader::fields(session_log)?
                    .iter()
                    .any(|f| matches!(f, Field::Varint(1, 1)));
                if start {
                    values.push(EventValue::SessionStart);
                }
            }
            Field::Bytes(5, summary) => {
                for entry in Reader::fields(summary)? {
                    if let Field::Bytes(1, value) = entry {
                        values.push(summary_value(value)?);
                    }
                }
            }
            _ => {}
        }
    }
    Some(
        values
            .into_iter()
            .map(|value| Event { step, value })
            .collect(),
    )
}

/// Reads an event file back, checking every record's CRCs; a torn last
/// record (a run killed mid-write) is left out.
pub fn read_events(path: &Path) -> Result<Vec<Event>, String> {
    let bytes = std::fs::read(path).map_err(|e| format!("{}: {e}", path.display()))?;
    let corrupt = |what: &str| format!("{}: not a TensorBoard event file: {what}", path.display());
    let mut events = Vec::new();
    let mut rest = bytes.as_slice();
    while rest.len() >= 12 {
        let (length, tail) = rest.split_at(8);
        let crc = u32::from_le_bytes([tail[0], tail[1], tail[2], tail[3]]);
        if crc != masked_crc(length) {
            return Err(corrupt("bad length checksum"));
        }
        let n = u64::from_le_bytes(length.try_into().map_err(|_| corrupt("short record"))?);
        let n = usize::try_from(n).map_err(|_| corrupt("record too long"))?;
        let body = &tail[4..];
        if body.len() < n.saturating_add(4) {
            break; // torn last record
        }
        let (payload, after) = body.split_at(n);
        let crc = u32::from_le_bytes([after[0], after[1], after[2], after[3]]);
        if crc != masked_crc(payload) {
            return Err(corrupt("bad payload checksum"));
        }
        events.extend(decode_event(payload).ok_or_else(|| corrupt("bad event"))?);
        rest = &after[4..];
    }
    Ok(events)
}

/// The events TensorBoard shows for a run whose event `files` (each one's
/// events, oldest file first) were written by successive sessions: a
/// `SessionLog` START at step `s` discards every earlier point at step `s`
/// or later, as TensorBoard's `EventAccumulator` purges a restarted run.
pub fn as_tensorboard_shows(files: Vec<Vec<Event>>) -> Vec<Event> {
    let mut shown: Vec<Event> = Vec::new();
    for event in files.into_iter().flatten() {
        if event.value == EventValue::SessionStart {
            shown.retain(|earlier| earlier.step < event.step);
        }
        shown.push(event);
    }
    shown
}
