//! The list of the loss's terms: each is declared once here, with the
//! name its logs, TensorBoard tags, plots and parity fixtures use and the
//! letter of the progress line, and every per-term value is a [`Terms`]
//! indexed by it, so a new term is a new entry here (and its arithmetic
//! in [`super::S3Loss`]) rather than a field spelled out in each place
//! that reports, sums or sends the terms.

/// A term of the S3 loss.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Term {
    /// `mean(A |d_s - r d_t|)`, the geometry-consistency term.
    Geometry,
    /// `mean(M_s P_s)`, the photometric term, before `lambda_p`.
    Photometric,
    /// `L_s`, the edge-aware smoothness term, before `lambda_s`.
    Smoothness,
    /// The range term, before `lambda_r` ([`super::range::out_of_range`]).
    Range,
    /// The view term, before `lambda_v` ([`super::range::out_of_view`]).
    View,
}

impl Term {
    /// Number of terms.
    pub const COUNT: usize = 5;

    /// Every term, in the order logs, plots and the ranks' messages list them.
    pub const ALL: [Term; Term::COUNT] = [
        Term::Geometry,
        Term::Photometric,
        Term::Smoothness,
        Term::Range,
        Term::View,
    ];

    /// The term's name: its key in `train.jsonl` (and so its TensorBoard
    /// tag and its curve in `loss.png`) and in the parity fixtures.
    pub fn name(self) -> &'static str {
        match self {
            Term::Geometry => "geometry",
            Term::Photometric => "photometric",
            Term::Smoothness => "smoothness",
            Term::Range => "range",
            Term::View => "view",
        }
    }

    /// The term's label in the progress line.
    pub fn letter(self) -> char {
        match self {
            Term::Geometry => 'g',
            Term::Photometric => 'p',
            Term::Smoothness => 's',
            Term::Range => 'r',
            Term::View => 'v',
        }
    }

    /// The term's place in [`Term::ALL`].
    pub fn index(self) -> usize {
        self as usize
    }
}

/// One value per loss term, `None` for a term that is switched off.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Terms<T>([Option<T>; Term::COUNT]);

impl<T> Default for Terms<T> {
    fn default() -> Self {
        Self(std::array::from_fn(|_| None))
    }
}

impl<T> Terms<T> {
    /// The value of `term`, if it is on.
    pub fn get(&self, term: Term) -> Option<&T> {
        self.0[term.index()].as_ref()
    }

    /// Sets the value of `term`.
    pub fn set(&mut self, term: Term, value: T) {
        self.0[term.index()] = Some(value);
    }

    /// Every term with its value, in [`Term::ALL`]'s order.
    pub fn iter(&self) -> impl Iterator<Item = (Term, Option<&T>)> {
        Term::ALL.into_iter().zip(self.0.iter().map(Option::as_ref))
    }

    /// The values through `f`, the terms that are off staying off.
    pub fn map<U>(self, mut f: impl FnMut(Term, T) -> U) -> Terms<U> {
        let mut values = Term::ALL.into_iter().zip(self.0);
        Terms(std::array::from_fn(|_| {
            let (term, value) = values.next().expect("one value per term");
            value.map(|v| f(term, v))
        }))
    }

    /// [`Terms::map`] with a function that may fail: the first error.
    pub fn try_map<U, E>(self, mut f: impl FnMut(Term, T) -> Result<U, E>) -> Result<Terms<U>, E> {
        let mut out = Terms::default();
        for (term, value) in Term::ALL.into_iter().zip(self.0) {
            if let Some(value) = value {
                out.set(term, f(term, value)?);
            }
        }
        Ok(out)
    }
}

impl<T: Copy> Terms<T> {
    /// The value of `term`, if it is on.
    pub fn value(&self, term: Term) -> Option<T> {
        self.0[term.index()]
    }

    /// The terms whose values `value` gives for every term, in order.
    pub fn from_fn(mut value: impl FnMut(Term) -> Option<T>) -> Self {
        Self(Term::ALL.map(&mut value))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_term_is_listed_once_at_its_index_with_its_own_name_and_letter() {
        for (i, term) in Term::ALL.into_iter().enumerate() {
            assert_eq!(term.index(), i);
        }
        let names: std::collections::HashSet<_> = Term::ALL.map(Term::name).into();
        let letters: std::collections::HashSet<_> = Term::ALL.map(Term::letter).into();
        assert_eq!((names.len(), letters.len()), (Term::COUNT, Term::COUNT));
    }

    #[test]
    fn values_follow_their_terms_through_map() {
        let mut terms = Terms::default();
        terms.set(Term::Smoothness, 2.0_f32);
        terms.set(Term::View, 3.0);
        let doubled = terms.map(|_, v| f64::from(v) * 2.0);
        assert_eq!(doubled.value(Term::Smoothness), Some(4.0));
        assert_eq!(doubled.value(Term::View), Some(6.0));
        assert_eq!(doubled.value(Term::Geometry), None);
        let failed: Result<Terms<f32>, Term> = terms.try_map(|term, _| Err(term));
        assert_eq!(failed, Err(Term::Smoothness));
    }
}
