//! Triplet sampling (conventions §5): a reference view and, independently and with
//! replacement, a student target and a teacher target among the other
//! N - 1 views, so N (N - 1)^2 triplets per sample.

use mbs_core::geometry::{Rig, Side};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::error::BatchError;

/// One training triplet of view indices (0..N-1, left to right).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Triplet {
    /// Reference view `r`.
    pub reference: usize,
    /// The student's target view `t_s` (never `r`).
    pub student: usize,
    /// The teacher's target view `t_t` (never `r`; may equal `t_s`).
    pub teacher: usize,
}

impl Triplet {
    /// Side of the student's target relative to the reference.
    pub fn student_side(&self) -> Side {
        side(self.reference, self.student)
    }

    /// Side of the teacher's target relative to the reference.
    pub fn teacher_side(&self) -> Side {
        side(self.reference, self.teacher)
    }

    /// `r = |x_ts - x_r| / |x_tt - x_r|` on `rig` (paper eq. 4).
    pub fn ratio(&self, rig: &Rig) -> f64 {
        rig.baseline_ratio(self.reference, self.student, self.teacher)
    }
}

/// Side of `target` from `reference`; the two differ in every triplet.
fn side(reference: usize, target: usize) -> Side {
    if target > reference {
        Side::Right
    } else {
        Side::Left
    }
}

/// Every triplet of an `n_views` sample, in (reference, student, teacher)
/// lexicographic order: `n (n - 1)^2` of them.
pub fn all_triplets(n_views: usize) -> Result<Vec<Triplet>, BatchError> {
    if n_views < 2 {
        return Err(BatchError::TooFewViews(n_views));
    }
    let others = |reference: usize| (0..n_views).filter(move |&v| v != reference);
    Ok((0..n_views)
        .flat_map(|reference| {
            others(reference).flat_map(move |student| {
                others(reference).map(move |teacher| Triplet {
                    reference,
                    student,
                    teacher,
                })
            })
        })
        .collect())
}

/// Draws triplets uniformly, deterministically from a seed.
#[derive(Debug, Clone)]
pub struct TripletSampler {
    n_views: usize,
    rng: ChaCha8Rng,
}

impl TripletSampler {
    /// A sampler for samples of `n_views` views.
    pub fn new(n_views: usize, seed: u64) -> Result<Self, BatchError> {
        if n_views < 2 {
            return Err(BatchError::TooFewViews(n_views));
        }
        Ok(Self {
            n_views,
            rng: ChaCha8Rng::seed_from_u64(seed),
        })
    }

    /// The next triplet (see [`draw_triplet`]).
    pub fn sample(&mut self) -> Triplet {
        draw_triplet(self.n_views, &mut self.rng)
    }
}

/// A triplet of an `n_views` sample (`n_views >= 2`): reference uniform
/// over all views, each target uniform over the other N - 1, independently.
pub fn draw_triplet<R: Rng>(n_views: usize, rng: &mut R) -> Triplet {
    let reference = rng.random_range(0..n_views);
    let mut other = || {
        let pick = rng.random_range(0..n_views - 1);
        if pick >= reference { pick + 1 } else { pick }
    };
    let student = other();
    let teacher = other();
    Triplet {
        reference,
        student,
        teacher,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::HashMap;

    #[test]
    fn counts_are_n_times_n_minus_one_squared() {
        for (n, want) in [(2, 2), (3, 12), (5, 80)] {
            let triplets = all_triplets(n).expect("n >= 2");
            assert_eq!(triplets.len(), want);
            let unique: std::collections::HashSet<_> = triplets.iter().collect();
            assert_eq!(unique.len(), want);
            assert!(
                triplets
                    .iter()
                    .all(|t| t.student != t.reference && t.teacher != t.reference)
            );
        }
        assert_eq!(all_triplets(1), Err(BatchError::TooFewViews(1)));
    }

    #[test]
    fn sampler_is_deterministic_and_covers_all_triplets_uniformly() {
        let draw = |seed| {
            let mut sampler = TripletSampler::new(3, seed).expect("n >= 2");
            (0..12_000).map(|_| sampler.sample()).collect::<Vec<_>>()
        };
        let a = draw(7);
        assert_eq!(a, draw(7));
        assert_ne!(a, draw(8));
        let mut counts: HashMap<Triplet, usize> = HashMap::new();
        for t in &a {
            *counts.entry(*t).or_default() += 1;
        }
        assert_eq!(counts.len(), 12);
        // 1000 expected each; 5 sigma is about 150.
        assert!(
            counts.values().all(|&c| (850..=1150).contains(&c)),
            "{counts:?}"
        );
    }

    #[test]
    fn sides_and_ratio_on_the_mbs20k_rig() {
        let rig = Rig::mbs20k();
        let t = Triplet {
            reference: 1,
            student: 0,
            teacher: 4,
        };
        assert_eq!(t.student_side(), Side::Left);
        assert_eq!(t.teacher_side(), Side::Right);
        // Baselines 1 B and 3 B.
        assert!((t.ratio(&rig) - 1.0 / 3.0).abs() < 1e-12);
    }
}
