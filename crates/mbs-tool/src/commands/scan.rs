//! `mbs-tool scan`: an MBS20K folder -> a manifest, with its statistics.

use std::path::PathBuf;

use clap::Parser;
use mbs_core::inputs::InputFiles;
use mbs_dataset::pairs::manifest_files;

use crate::cli::rig::RigArgs;
use mbs_dataset::mbs20k::{Counts, ScanOptions, scan};

/// Arguments of `scan`.
#[derive(Parser)]
#[command(after_help = "Examples:
  mbs-tool scan /data/MBS20K                      # writes /data/MBS20K/manifest.json
  mbs-tool scan /data/MBS20K --test-towns Town10,Town05 --out mbs20k.json

Expects <root>/<Town>/<Weather>/<frame>/rgb_0.png … rgb_4.png, depth_0.png and
prints the number of sets per town and weather. Check the result with
`mbs-tool validate`.")]
pub struct Args {
    /// The MBS20K root folder.
    pub root: PathBuf,
    /// Where to write the manifest [default: ROOT/manifest.json]: in ROOT or
    /// a folder above it, since its paths are relative to its own folder
    /// and never climb out of it.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Towns whose samples form the test split.
    #[arg(long, value_delimiter = ',', default_value = "Town10", value_parser = crate::cli::values::folder_name)]
    pub test_towns: Vec<String>,
    #[command(flatten)]
    pub rig: RigArgs,
    /// Depth beyond this many metres is invalid for disparity.
    #[arg(long, default_value_t = 200.0, value_parser = crate::cli::values::positive, allow_negative_numbers = true)]
    pub max_depth: f64,
}

/// Runs `scan`.
pub fn run(args: Args) -> anyhow::Result<()> {
    let options = ScanOptions {
        rig: args.rig.rig(),
        test_towns: args.test_towns,
        max_depth_m: args.max_depth,
    };
    let mut manifest = scan(&args.root, &options)?;
    let named = args.out.is_some();
    let out = args.out.unwrap_or_else(|| args.root.join("manifest.json"));
    let out_dir = mbs_dataset::manifest::folder(&out);
    // A manifest's paths stay inside its folder (mbs_core::confine), so it
    // is written in ROOT or in a folder above it.
    let (out_abs, root_abs) = (
        std::path::absolute(&out_dir)?,
        std::path::absolute(&args.root)?,
    );
    if out_abs != root_abs {
        let prefix = mbs_core::confine::name_inside(&out_abs, &root_abs).ok_or_else(|| {
            anyhow::anyhow!(
                "--out {}: a manifest's paths must stay inside its folder, so write it in {} or in a folder above it",
                out.display(),
                args.root.display()
            )
        })?;
        manifest.rebase(std::path::Path::new(&prefix));
    }
    let mut inputs = InputFiles::new();
    inputs.extend(manifest_files(&out, &manifest));
    inputs.refuse(&out)?;
    // The default name in the dataset's own folder: a manifest.json there
    // that mbs did not write is the dataset's, never replaced.
    let _out = match named {
        true => None,
        false => Some(crate::cli::take_out(
            &args.root,
            None,
            "scan",
            &inputs,
            std::slice::from_ref(&out),
        )?),
    };
    manifest.save(&out)?;
    print!("{}", Counts::of(&manifest).table());
    eprintln!(
        "scan: {} samples -> {}",
        manifest.samples.len(),
        out.display()
    );
    Ok(())
}
