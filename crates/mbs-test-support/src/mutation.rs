//! Deterministic mutations of valid files, for the readers' fuzz tests:
//! bit flips, truncation, inserted bytes, duplicated spans and absurd
//! numbers written over a header's numbers. A seed gives the same cases on
//! every machine, so a failure found in CI replays anywhere.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// The generator mutations are drawn from: seeded, the same on every machine.
pub type MutationRng = ChaCha8Rng;

/// A number in `0..n` (0 when `n` is 0).
fn below(rng: &mut MutationRng, n: usize) -> usize {
    rng.random_range(0..n.max(1))
}

/// Numbers that break naive size arithmetic when written into a header.
const ABSURD_NUMBERS: [&str; 8] = [
    "0",
    "-1",
    "2147483648",
    "4294967295",
    "18446744073709551615",
    "99999999999999999999999",
    "1e309",
    "NaN",
];

/// One mutation of `valid`, chosen by `rng`. Header-number mutations
/// replace one ASCII digit run in the first 64 bytes; binary headers get
/// their first bytes overwritten with `0xFF` runs instead.
pub fn mutate(valid: &[u8], rng: &mut MutationRng) -> Vec<u8> {
    let mut bytes = valid.to_vec();
    let len = bytes.len().max(1);
    match below(rng, 6) {
        0 => {
            for _ in 0..1 + below(rng, 8) {
                let at = below(rng, len).min(bytes.len().saturating_sub(1));
                if let Some(b) = bytes.get_mut(at) {
                    *b ^= 1 << below(rng, 8);
                }
            }
        }
        1 => bytes.truncate(below(rng, len)),
        2 => {
            let at = below(rng, len + 1).min(bytes.len());
            let inserted: Vec<u8> = (0..1 + below(rng, 32))
                .map(|_| rng.random::<u8>())
                .collect();
            bytes.splice(at..at, inserted);
        }
        3 => {
            let start = below(rng, len).min(bytes.len());
            let end = (start + 1 + below(rng, 64)).min(bytes.len());
            let span = bytes[start..end].to_vec();
            bytes.splice(start..start, span);
        }
        4 => {
            let head = bytes.len().min(64);
            let runs: Vec<(usize, usize)> = digit_runs(&bytes[..head]);
            if runs.is_empty() {
                let at = below(rng, head.max(1)).min(bytes.len());
                let end = (at + 4).min(bytes.len());
                bytes[at..end].fill(0xFF);
            } else {
                let (start, end) = runs[below(rng, runs.len())];
                let number = ABSURD_NUMBERS[below(rng, ABSURD_NUMBERS.len())];
                bytes.splice(start..end, number.bytes());
            }
        }
        _ => {
            let at = below(rng, len).min(bytes.len());
            let end = (at + 1 + below(rng, 16)).min(bytes.len());
            bytes[at..end].fill(if below(rng, 2) == 0 { 0 } else { 0xFF });
        }
    }
    bytes
}

/// What a fuzz run of one reader found.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct FuzzSummary {
    /// Mutated files read.
    pub cases: usize,
    /// Files the reader refused with an error.
    pub refused: usize,
    /// Files the reader panicked on, or refused without naming the file.
    pub failures: Vec<String>,
}

/// Writes `cases` mutations of `valid` into `dir` (as `case-N.EXT`, one at
/// a time), reads each with `read` and records panics and errors that do
/// not name the file. Deterministic for a `seed`.
pub fn fuzz_reader<E: std::fmt::Display>(
    valid: &[u8],
    dir: &std::path::Path,
    ext: &str,
    (cases, seed): (usize, u64),
    read: impl Fn(&std::path::Path) -> std::result::Result<(), E>,
) -> std::io::Result<FuzzSummary> {
    let mut rng = MutationRng::seed_from_u64(seed);
    let mut summary = FuzzSummary::default();
    for case in 0..cases {
        let name = format!("case-{case}.{ext}");
        let path = dir.join(&name);
        std::fs::write(&path, mutate(valid, &mut rng))?;
        match std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| read(&path))) {
            Err(_) => summary.failures.push(format!("{name}: panicked")),
            Ok(Err(e)) if !e.to_string().contains(&name) => {
                summary
                    .failures
                    .push(format!("{name}: error without the file name: {e}"));
            }
            Ok(Err(_)) => summary.refused += 1,
            Ok(Ok(())) => {}
        }
        summary.cases += 1;
        std::fs::remove_file(&path)?;
    }
    Ok(summary)
}

/// The `(start, end)` of every run of ASCII digits in `bytes`.
fn digit_runs(bytes: &[u8]) -> Vec<(usize, usize)> {
    let mut runs = Vec::new();
    let mut i = 0;
    while i < bytes.len() {
        if bytes[i].is_ascii_digit() {
            let start = i;
            while i < bytes.len() && bytes[i].is_ascii_digit() {
                i += 1;
            }
            runs.push((start, i));
        } else {
            i += 1;
        }
    }
    runs
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mutations_are_deterministic_and_change_the_bytes() {
        let valid = b"Pf\n4 3\n-1.0\n0123456789abcdef".to_vec();
        let (mut a, mut b) = (MutationRng::seed_from_u64(7), MutationRng::seed_from_u64(7));
        let mut changed = 0;
        for _ in 0..200 {
            let m = mutate(&valid, &mut a);
            assert_eq!(m, mutate(&valid, &mut b));
            changed += usize::from(m != valid);
        }
        assert!(changed > 180, "{changed} of 200 mutations changed the file");
        assert_eq!(digit_runs(b"P6 12 7"), vec![(1, 2), (3, 5), (6, 7)]);
    }
}
