//! TensorBoard event files, so a run can be watched and compared with
//! `tensorboard --logdir RUN` like the runs of other stereo training code.
//!
//! A file is a sequence of records: the payload length (u64, little
//! endian), the masked CRC-32C of those 8 bytes, the payload, and the
//! masked CRC-32C of the payload. Each payload is an `Event` protocol
//! buffer: the first holds the file version, the others a `Summary` with
//! scalars (`simple_value`) or PNG images. The few protobuf fields needed
//! are written here directly (the tests read them back with
//! `mbs_test_support::events`).

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::time::{SystemTime, UNIX_EPOCH};

use crate::error::TrainError;

/// The version string of the first event of every file.
const FILE_VERSION: &str = "brain.Event:2";
/// `SessionLog.SessionStatus.START`.
const SESSION_START: u64 = 1;
/// TensorBoard's CRC mask constant.
const MASK_DELTA: u32 = 0xa282_ead8;

/// The masked CRC-32C that TensorBoard's records carry.
fn masked_crc(bytes: &[u8]) -> u32 {
    let crc = crc32c::crc32c(bytes);
    crc.rotate_right(15).wrapping_add(MASK_DELTA)
}

/// Appends a protobuf varint.
fn varint(out: &mut Vec<u8>, mut value: u64) {
    while value >= 0x80 {
        out.push((value as u8) | 0x80);
        value >>= 7;
    }
    out.push(value as u8);
}

/// Appends a length-delimited field (wire type 2).
fn bytes_field(out: &mut Vec<u8>, field: u32, bytes: &[u8]) {
    varint(out, u64::from(field << 3 | 2));
    varint(out, bytes.len() as u64);
    out.extend_from_slice(bytes);
}

/// Appends a varint field (wire type 0).
fn varint_field(out: &mut Vec<u8>, field: u32, value: u64) {
    varint(out, u64::from(field << 3));
    varint(out, value);
}

/// An `Event` with its wall time, step and one more encoded field.
fn event(step: u64, body: impl FnOnce(&mut Vec<u8>)) -> Vec<u8> {
    let wall_time = SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0.0, |d| d.as_secs_f64());
    let mut out = Vec::new();
    varint(&mut out, 1 << 3 | 1); // wall_time: double
    out.extend_from_slice(&wall_time.to_le_bytes());
    varint_field(&mut out, 2, step);
    body(&mut out);
    out
}

/// A `Summary` of one value, as field 5 of an event.
fn summary(out: &mut Vec<u8>, tag: &str, value: impl FnOnce(&mut Vec<u8>)) {
    let mut entry = Vec::new();
    bytes_field(&mut entry, 1, tag.as_bytes());
    value(&mut entry);
    let mut summary = Vec::new();
    bytes_field(&mut summary, 1, &entry);
    bytes_field(out, 5, &summary);
}

/// Writes one event file.
pub struct EventWriter {
    path: PathBuf,
    file: BufWriter<File>,
}

impl EventWriter {
    /// Creates a new event file in `dir` (created if missing), named as
    /// TensorBoard expects (`events.out.tfevents.<seconds>.<name>`), and
    /// writes its version event. A resumed run adds a file beside the
    /// earlier ones; TensorBoard reads them all.
    pub fn create(dir: &Path) -> Result<Self, TrainError> {
        std::fs::create_dir_all(dir).map_err(|e| TrainError::data(dir, e))?;
        let now = SystemTime::now()
            .duration_since(UNIX_EPOCH)
            .map_or(0, |d| d.as_secs());
        let mut path = dir.join(format!("events.out.tfevents.{now}.mbs"));
        let mut n = 1;
        while path.exists() {
            path = dir.join(format!("events.out.tfevents.{now}.mbs.{n}"));
            n += 1;
        }
        let file = File::create(&path).map_err(|e| TrainError::data(&path, e))?;
        let mut writer = Self {
            path,
            file: BufWriter::new(file),
        };
        writer.record(&event(0, |out| {
            bytes_field(out, 3, FILE_VERSION.as_bytes())
        }))?;
        writer.flush()?;
        Ok(writer)
    }

    /// The file written.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Appends one record.
    fn record(&mut self, payload: &[u8]) -> Result<(), TrainError> {
        let length = (payload.len() as u64).to_le_bytes();
        let mut record = Vec::with_capacity(payload.len() + 16);
        record.extend_from_slice(&length);
        record.extend_from_slice(&masked_crc(&length).to_le_bytes());
        record.extend_from_slice(payload);
        record.extend_from_slice(&masked_crc(payload).to_le_bytes());
        self.file
            .write_all(&record)
            .map_err(|e| TrainError::data(&self.path, e))
    }

    /// Marks a resumed run: a `SessionLog` START event at `step`, on
    /// which TensorBoard discards the points of earlier files at `step`
    /// and after (those a killed run logged past its last checkpoint, which
    /// the resumed run logs again).
    pub fn session_start(&mut self, step: u64) -> Result<(), TrainError> {
        let payload = event(step, |out| {
            let mut session_log = Vec::new();
            varint_field(&mut session_log, 1, SESSION_START);
            bytes_field(out, 7, &session_log); // Event.session_log
        });
        self.record(&payload)
    }

    /// Logs `value` under `tag` at `step`.
    pub fn scalar(&mut self, tag: &str, step: u64, value: f32) -> Result<(), TrainError> {
        let payload = event(step, |out| {
            summary(out, tag, |entry| {
                varint(entry, 2 << 3 | 5); // simple_value: float
                entry.extend_from_slice(&value.to_le_bytes());
            })
        });
        self.record(&payload)
    }

    /// Logs a PNG image of `width` x `height` RGB pixels under `tag`.
    pub fn image(
        &mut self,
        tag: &str,
        step: u64,
        (width, height): (u32, u32),
        png: &[u8],
    ) -> Result<(), TrainError> {
        let payload = event(step, |out| {
            summary(out, tag, |entry| {
                let mut image = Vec::new();
                varint_field(&mut image, 1, u64::from(height));
                varint_field(&mut image, 2, u64::from(width));
                varint_field(&mut image, 3, 3); // colorspace: RGB
                bytes_field(&mut image, 4, png);
                bytes_field(entry, 4, &image);
            })
        });
        self.record(&payload)
    }

    /// Writes buffered records to the file.
    pub fn flush(&mut self) -> Result<(), TrainError> {
        self.file
            .flush()
            .map_err(|e| TrainError::data(&self.path, e))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use mbs_test_support::events::{Event, EventValue, read_events};

    #[test]
    fn masked_crc_of_the_standard_check_input() {
        // CRC-32C("123456789") is 0xe3069283 (the standard check value);
        // TensorFlow masks it as ((crc >> 15) | (crc << 17)) + 0xa282ead8,
        // worked out by hand.
        assert_eq!(crc32c::crc32c(b"123456789"), 0xe306_9283);
        assert_eq!(masked_crc(b"123456789"), 0xc78a_b0e5);
    }

    #[test]
    fn scalars_and_images_read_back() {
        let dir = tempfile::tempdir().unwrap();
        let mut writer = EventWriter::create(dir.path()).unwrap();
        writer.scalar("train/loss", 10, 0.25).unwrap();
        writer.scalar("val/ALL/out3", 20, 4.5).unwrap();
        writer
            .image("val/sheet", 20, (3, 2), b"\x89PNG fake")
            .unwrap();
        writer.session_start(21).unwrap();
        writer.flush().unwrap();
        let name = writer
            .path()
            .file_name()
            .unwrap()
            .to_string_lossy()
            .into_owned();
        assert!(name.starts_with("events.out.tfevents."), "{name}");
        let events = read_events(writer.path()).unwrap();
        assert_eq!(
            events,
            [
                Event {
                    step: 0,
                    value: EventValue::FileVersion(FILE_VERSION.into())
                },
                Event {
                    step: 10,
                    value: EventValue::Scalar("train/loss".into(), 0.25)
                },
                Event {
                    step: 20,
                    value: EventValue::Scalar("val/ALL/out3".into(), 4.5)
                },
                Event {
                    step: 20,
                    value: EventValue::Image("val/sheet".into(), (3, 2), b"\x89PNG fake".to_vec())
                },
                Event {
                    step: 21,
                    value: EventValue::SessionStart
                },
            ]
        );
        // A second writer in the same folder gets its own file.
        let other = EventWriter::create(dir.path()).unwrap();
        assert_ne!(other.path(), writer.path());
    }

    #[test]
    fn torn_records_are_dropped_and_flipped_bits_refused() {
        let dir = tempfile::tempdir().unwrap();
        let mut writer = EventWriter::create(dir.path()).unwrap();
        writer.scalar("a", 1, 1.0).unwrap();
        writer.flush().unwrap();
        let path = writer.path().to_path_buf();
        let bytes = std::fs::read(&path).unwrap();
        std::fs::write(&path, &bytes[..bytes.len() - 3]).unwrap();
        assert_eq!(read_events(&path).unwrap().len(), 1);
        let mut flipped = bytes.clone();
        let last = flipped.len() - 6;
        flipped[last] ^= 0x40;
        std::fs::write(&path, &flipped).unwrap();
        let err = read_events(&path).unwrap_err().to_string();
        assert!(err.contains("bad payload checksum"), "{err}");
    }
}
