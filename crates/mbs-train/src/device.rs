//! Where training runs: burn's `flex` CPU backend always, NVIDIA GPUs when
//! the crate is built with the `cuda` feature (burn's CubeCL CUDA backend).

use burn::tensor::Device;

use crate::error::TrainError;

/// The device named `cpu`, `cuda` or `cuda:N`.
pub fn parse_device(name: &str) -> Result<Device, TrainError> {
    let unavailable = |feature: &str| {
        Err(TrainError::Config(format!(
            "device `{name}` needs a build with the `{feature}` feature (cargo build --release -p mbs-tool --features {feature})"
        )))
    };
    match name {
        "cpu" => Ok(Device::flex()),
        _ => {
            let Some(index) = cuda_index(name) else {
                return Err(TrainError::Config(format!(
                    "unknown device `{name}`: use cpu, cuda or cuda:N"
                )));
            };
            #[cfg(feature = "cuda")]
            return Ok(Device::cuda(index));
            #[cfg(not(feature = "cuda"))]
            {
                let _ = index;
                unavailable("cuda")
            }
        }
    }
}

/// `N` of `cuda` (0) or `cuda:N`.
fn cuda_index(name: &str) -> Option<usize> {
    match name.strip_prefix("cuda")? {
        "" => Some(0),
        rest => rest.strip_prefix(':')?.parse().ok(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_are_parsed_and_unknown_ones_refused() {
        assert!(parse_device("cpu").is_ok());
        assert_eq!(cuda_index("cuda"), Some(0));
        assert_eq!(cuda_index("cuda:3"), Some(3));
        assert_eq!(cuda_index("cuda3"), None);
        let message = parse_device("tpu").expect_err("unknown").to_string();
        assert!(message.contains("unknown device `tpu`"), "{message}");
        #[cfg(not(feature = "cuda"))]
        {
            let message = parse_device("cuda:1")
                .expect_err("no CUDA build")
                .to_string();
            assert!(message.contains("--features cuda"), "{message}");
        }
    }
}
