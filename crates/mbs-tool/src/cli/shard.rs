//! `--shard K/N`: split a batch between the N jobs of a cluster job array;
//! job K (0-based) takes items K, K+N, K+2N… of the sorted item list.

use std::str::FromStr;

/// One of N shards of a batch.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Shard {
    /// This job's index, 0-based.
    pub index: usize,
    /// The number of jobs.
    pub count: usize,
}

impl FromStr for Shard {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let usage = || format!("invalid shard {s:?}: expected K/N with 0 <= K < N, e.g. 0/4");
        let (k, n) = s.split_once('/').ok_or_else(usage)?;
        let index: usize = k.trim().parse().map_err(|_| usage())?;
        let count: usize = n.trim().parse().map_err(|_| usage())?;
        if count == 0 || index >= count {
            return Err(usage());
        }
        Ok(Shard { index, count })
    }
}

impl Shard {
    /// Keeps this shard's items of an already sorted list.
    pub fn select<T>(self, items: Vec<T>) -> Vec<T> {
        items
            .into_iter()
            .enumerate()
            .filter(|(i, _)| i % self.count == self.index)
            .map(|(_, item)| item)
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_and_selects_round_robin() {
        let shard: Shard = "1/3".parse().unwrap();
        assert_eq!(shard.select((0..8).collect()), vec![1, 4, 7]);
    }

    #[test]
    fn shards_cover_everything_once() {
        let mut all: Vec<i32> = (0..3)
            .flat_map(|k| Shard { index: k, count: 3 }.select((0..10).collect()))
            .collect();
        all.sort();
        assert_eq!(all, (0..10).collect::<Vec<_>>());
    }

    #[test]
    fn rejects_bad_shards() {
        for bad in ["3/3", "1", "a/2", "0/0", "-1/2"] {
            assert!(
                bad.parse::<Shard>().unwrap_err().contains("expected K/N"),
                "{bad}"
            );
        }
    }
}
