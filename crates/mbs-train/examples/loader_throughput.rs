//! Measures the training data pipeline alone ([`BatchLoader`]: drawing
//! triplets and crops, decoding the PNG views, cropping into `[B, 3, H, W]`
//! buffers) at MBS20K scale, for several numbers of loading threads, so
//! that its samples/s can be set against the step rate it must feed. Run
//! in release:
//!
//! ```text
//! cargo run --release -p mbs-train --example loader_throughput -- \
//!     [--manifest M.json] [--frames 6] [--batch 16] [--crop 384x512] [--steps 12] [--workers 1,2]
//! ```
//!
//! Without `--manifest` it renders an MBS20K-style set first (`--frames`
//! scenes of 5 views at 960x540, one town and weather) into a temporary
//! folder. After one warm-up pass over the batches (so the files are in
//! the page cache, as in a long run), it times `--steps` batches per
//! worker count and prints one JSON line each:
//!
//! ```text
//! {"workers":2,"batch":16,"crop":[384,512],"steps":12,"samples_per_s":...,"ms_per_batch":...}
//! ```

use std::path::PathBuf;
use std::sync::Arc;
use std::time::Instant;

use mbs_core::Rig;
use mbs_synth::dataset::DatasetSpec;
use mbs_synth::{SceneConfig, Weather};
use mbs_train::data::{BatchLoader, TrainingSamples};

/// The command-line settings.
struct Settings {
    manifest: Option<PathBuf>,
    frames: usize,
    batch: usize,
    crop: (usize, usize),
    steps: usize,
    workers: Vec<usize>,
}

fn parse() -> Result<Settings, String> {
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let mut settings = Settings {
        manifest: None,
        frames: 6,
        batch: 16,
        crop: (384, 512),
        steps: 12,
        workers: vec![1, cores],
    };
    let args: Vec<String> = std::env::args().skip(1).collect();
    for pair in args.chunks(2) {
        let [flag, value] = pair else {
            return Err(format!("{} needs a value", pair[0]));
        };
        let number = |v: &str| v.parse::<usize>().map_err(|e| format!("{flag} {v}: {e}"));
        match flag.as_str() {
            "--manifest" => settings.manifest = Some(PathBuf::from(value)),
            "--frames" => settings.frames = number(value)?,
            "--batch" => settings.batch = number(value)?,
            "--steps" => settings.steps = number(value)?,
            "--crop" => {
                let (h, w) = value
                    .split_once('x')
                    .ok_or_else(|| format!("--crop {value}: expected HxW"))?;
                settings.crop = (number(h)?, number(w)?);
            }
            "--workers" => {
                settings.workers = value.split(',').map(number).collect::<Result<_, _>>()?;
            }
            _ => return Err(format!("unknown flag {flag}")),
        }
    }
    Ok(settings)
}

/// Renders `frames` MBS20K-style scenes (5 cameras 0.5 m apart, 960x540)
/// under `root` and returns the manifest's path.
fn render(root: &std::path::Path, frames: usize) -> Result<PathBuf, Box<dyn std::error::Error>> {
    let spec = DatasetSpec {
        rig: Rig::centred(5, 0.5, 480.0, 960, 540),
        towns: vec!["Town01".into()],
        weathers: vec![Weather::ClearNoon],
        frames,
        seed: 7,
        test_towns: Vec::new(),
        scene: SceneConfig::default(),
        supersample: 1,
        max_depth_m: 200.0,
        checksums: false,
    };
    for frame in spec.frames() {
        spec.write_frame(root, &frame)?;
    }
    let path = root.join("manifest.json");
    spec.manifest(root)?.save(&path)?;
    Ok(path)
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let settings = parse()?;
    let scratch = tempfile::tempdir()?;
    let manifest = match &settings.manifest {
        Some(path) => path.clone(),
        None => render(scratch.path(), settings.frames)?,
    };
    let samples = Arc::new(TrainingSamples::load(&manifest, settings.crop)?);
    let pass = |workers: usize| -> Result<f64, Box<dyn std::error::Error>> {
        let start = Instant::now();
        let mut loader = BatchLoader::start(
            Arc::clone(&samples),
            (settings.batch, 0..settings.batch),
            settings.crop,
            1,
            (0, settings.steps),
            workers,
        );
        while let Some(batch) = loader.next_batch() {
            batch?;
        }
        Ok(start.elapsed().as_secs_f64())
    };
    pass(settings.workers.iter().copied().max().unwrap_or(1))?; // warm the page cache
    for &workers in &settings.workers {
        let seconds = pass(workers)?;
        let line = serde_json::json!({
            "workers": workers,
            "batch": settings.batch,
            "crop": [settings.crop.0, settings.crop.1],
            "steps": settings.steps,
            "samples_per_s": (settings.steps * settings.batch) as f64 / seconds,
            "ms_per_batch": 1e3 * seconds / settings.steps as f64,
        });
        println!("{line}");
    }
    Ok(())
}
