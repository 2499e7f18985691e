//! The message MPI ranks exchange after each share's backward pass: the
//! share's loss values ([`LossValues`]), its weight and its gradient
//! length, as little-endian f64s, the loss terms in [`Term::ALL`]'s order.

use super::objective::LossValues;
use crate::losses::{Term, Terms};
use crate::supervision::Supervision;

impl LossValues {
    /// Number of f64s [`Self::encode`] writes: weight, gradient length and
    /// total, a flag and a value for each term and each of the two masks,
    /// and the four disparity statistics.
    const ENCODED_FLOATS: usize = 3 + 2 * (Term::COUNT + 2) + 4;

    /// The values, the share's weight and its gradient length as bytes,
    /// for the other ranks ([`Self::decode`]): f64s, each optional one
    /// preceded by 1 (present) or 0, the terms in [`Term::ALL`]'s order.
    pub(super) fn encode(&self, weight: f64, gradient_length: usize) -> Vec<u8> {
        let s = &self.supervision;
        let optional = Term::ALL
            .map(|term| self.terms.value(term))
            .into_iter()
            .chain([s.student_mask, s.teacher_mask]);
        let mut floats = vec![weight, gradient_length as f64, f64::from(self.total)];
        for value in optional {
            floats.push(f64::from(u8::from(value.is_some())));
            floats.push(value.map_or(0.0, f64::from));
        }
        floats.extend(
            [
                s.disparity_min,
                s.disparity_mean,
                s.disparity_max,
                s.outside,
            ]
            .map(f64::from),
        );
        floats.iter().flat_map(|v| v.to_le_bytes()).collect()
    }

    /// What [`Self::encode`] wrote: the values, the weight and the gradient
    /// length; `None` for bytes of another length.
    pub(super) fn decode(bytes: &[u8]) -> Option<(Self, f64, usize)> {
        let floats: Vec<f64> = bytes
            .chunks_exact(8)
            .map(|chunk| f64::from_le_bytes(chunk.try_into().unwrap_or_default()))
            .collect();
        if floats.len() != Self::ENCODED_FLOATS || bytes.len() != Self::ENCODED_FLOATS * 8 {
            return None;
        }
        let optional = |i: usize| (floats[3 + 2 * i] == 1.0).then(|| floats[4 + 2 * i] as f32);
        let terms = Terms::from_fn(|term| optional(term.index()));
        let statistics = &floats[3 + 2 * (Term::COUNT + 2)..];
        let values = Self {
            total: floats[2] as f32,
            terms,
            supervision: Supervision {
                student_mask: optional(Term::COUNT),
                teacher_mask: optional(Term::COUNT + 1),
                disparity_min: statistics[0] as f32,
                disparity_mean: statistics[1] as f32,
                disparity_max: statistics[2] as f32,
                outside: statistics[3] as f32,
            },
        };
        Some((values, floats[0], floats[1] as usize))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_message_reads_back_as_sent_and_one_of_another_length_is_refused() {
        let mut terms = Terms::default();
        terms.set(Term::Geometry, 0.5);
        terms.set(Term::View, 0.25);
        let values = LossValues {
            total: 1.5,
            terms,
            supervision: Supervision {
                student_mask: Some(0.75),
                teacher_mask: None,
                disparity_min: -1.0,
                disparity_mean: 3.0,
                disparity_max: 9.0,
                outside: 0.125,
            },
        };
        let bytes = values.encode(0.5, 1234);
        assert_eq!(bytes.len(), LossValues::ENCODED_FLOATS * 8);
        assert_eq!(LossValues::decode(&bytes), Some((values, 0.5, 1234)));
        assert_eq!(LossValues::decode(&bytes[..bytes.len() - 8]), None);
    }
}
