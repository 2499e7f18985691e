//! Seeded weights that the parity fixtures' script reproduces bit for bit
//! (`tools/parity/seeded_weights.py`): every tensor is filled from its
//! official state-dict key, so the fixtures carry inputs and outputs but no
//! weights.
//!
//! A SplitMix64 stream seeded with the FNV-1a hash of the key gives 24-bit
//! uniforms `u` in `[0, 1)`; by the key's last part: a convolution weight
//! (two dimensions or more) is `(2u - 1) sqrt(6 / fan_in)` with `fan_in` the
//! product of all dimensions but the first, another weight
//! `1 + 0.2 (2u - 1)`, a bias or
//! running mean `0.1 (2u - 1)`, a running variance `1 + 0.5 u`.

/// `count` uniforms in `[0, 1)` from the stream of `key`.
pub fn uniforms(key: &str, count: usize) -> Vec<f32> {
    let seed = key.bytes().fold(0xCBF2_9CE4_8422_2325u64, |h, byte| {
        (h ^ u64::from(byte)).wrapping_mul(0x0100_0000_01B3)
    });
    (1..=count as u64)
        .map(|i| {
            let mut z = seed.wrapping_add(i.wrapping_mul(0x9E37_79B9_7F4A_7C15));
            z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
            z ^= z >> 31;
            (z >> 40) as f32 / (1u32 << 24) as f32
        })
        .collect()
}

/// The seeded values of the tensor `key` of `shape`, or `None` for a key
/// the rule does not cover.
pub fn seeded_tensor(key: &str, shape: &[usize]) -> Option<Vec<f32>> {
    let u = uniforms(key, shape.iter().product());
    let name = key.rsplit('.').next().unwrap_or(key);
    let scaled = |scale: f32, offset: f32| -> Vec<f32> {
        u.iter()
            .map(|&u| offset + (2.0 * u - 1.0) * scale)
            .collect()
    };
    match name {
        "weight" if shape.len() >= 2 => {
            let fan_in: usize = shape[1..].iter().product();
            Some(scaled((6.0 / fan_in as f64).sqrt() as f32, 0.0))
        }
        "weight" => Some(scaled(0.2, 1.0)),
        "bias" | "running_mean" => Some(scaled(0.1, 0.0)),
        "running_var" => Some(u.iter().map(|&u| 1.0 + u * 0.5).collect()),
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn matches_the_python_generator() {
        // tools/parity/seeded_weights.py: uniforms("a.weight", 4) and
        // seeded_tensor("x.bias", (3,)).
        let u = uniforms("a.weight", 4);
        let want = [0.6705318, 0.22916943, 0.90333384, 0.9772796];
        assert!(
            u.iter().zip(want).all(|(a, b)| (a - b).abs() < 1e-7),
            "{u:?}"
        );
        let bias = seeded_tensor("x.bias", &[3]).expect("covered");
        let want = [-0.08385787, -0.09350347, 0.0102609];
        assert!(
            bias.iter().zip(want).all(|(a, b)| (a - b).abs() < 1e-7),
            "{bias:?}"
        );
    }
}
