//! Launching a run: from the typed device list, the processes a launcher
//! (`mpirun`, `srun`) started, the run's paths and its flags, to an open
//! [`TrainingRun`], for any front end (the CLI's `train`, the demo, a
//! binding). [`Launch::open`] opens the devices under one consensus,
//! checks the inputs, agrees once across the ranks on everything they
//! must share, lets the one writer prepare the folder and hands back the
//! run; [`settle`] is how the ranks end on an error.
//!
//! Every check comes before anything is removed or written: a refused
//! launch leaves the output folder as it was (or absent), but for its lock
//! file, which the run takes first and writes its name in.

mod devices;
mod processes;
mod ranks;
mod stop;

use std::path::Path;
use std::rc::Rc;
use std::sync::atomic::AtomicBool;

use mbs_core::inputs::InputFiles;
use mbs_core::out_dir::OutDir;
use mbs_nets::checkpoint::{CHECKPOINTS_DIR, TrainedNetworks};
use mbs_nets::device::{DeviceList, DeviceName};
use thiserror::Error;

use crate::checkpoint::Checkpoint;
use crate::config::RunConfig;
use crate::data::validation::ValidationMetrics;
use crate::distributed::{Collective, agree, all_succeeded};
use crate::error::TrainError;
use crate::run::{End, Observer, Quiet, Start, Strategy, TrainingRun, open, place};
use crate::step::GradientReduction;
use mbs_nets::StereoNetwork;

pub use processes::{MpiJoin, join};
pub use ranks::{ReportedByRankZero, Stopped, settle};
pub use stop::stop_requests;

/// What a run is launched from.
pub struct Launch<'a> {
    /// The dataset manifest.
    pub manifest: &'a Path,
    /// The run's output folder.
    pub out: &'a Path,
    /// The run's settings (a resumed run's: its checkpoint's, overlaid).
    pub config: RunConfig,
    /// The devices, as the user listed them (each rank of several takes
    /// its part of the list on its machine).
    pub devices: &'a DeviceList,
    /// The processes the run is spread over (`None`: this one alone).
    pub processes: Option<Rc<dyn Collective>>,
    /// Where the first weights come from.
    pub beginning: Beginning<'a>,
    /// How the processes sum their gradients (`None`: through one host
    /// buffer, [`crate::step::HostAllReduce`]); a reduction written
    /// elsewhere (a device-side collective) must sum over `processes`.
    pub reduction: Option<Rc<dyn GradientReduction<StereoNetwork>>>,
}

/// Where a run's first weights come from.
#[derive(Debug, Clone, Copy, Default)]
pub struct Beginning<'a> {
    /// Weights a new run starts from (another run, a checkpoint, an
    /// official file), instead of fresh ones.
    pub init: Option<&'a Path>,
    /// Start again from fresh (or `init`'s) weights, discarding the run's
    /// checkpoints.
    pub restart: bool,
}

/// A launched run.
pub struct Launched {
    /// The run, ready to train.
    pub run: TrainingRun,
    /// How it began.
    pub start: Start,
    /// Warnings for the user (the memory a step needs), on the writer.
    pub warnings: Vec<String>,
    /// Temporary files a killed earlier run had left in the folder, removed.
    pub removed_partials: usize,
}

/// Why a run could not be launched.
#[derive(Debug, Error)]
pub enum LaunchError {
    /// The devices cannot run the settings (more sharers than batch items,
    /// no device): a usage error.
    #[error("{0}")]
    Usage(String),
    /// The launcher's variables give no rank of their launch.
    #[error("{0}")]
    Launcher(String),
    /// The launcher started several processes, and the front end cannot
    /// join them into an MPI job: each would train alone into the same
    /// folder.
    #[error(
        "the launcher started {launched} processes, but this program cannot join an MPI job, \
         so each would train alone into the same folder: run one process"
    )]
    NoMpi {
        /// The processes the launcher's variables announce.
        launched: usize,
    },
    /// MPI was initialised before the run joined it.
    #[error("MPI was already initialised in this process")]
    MpiInitialised,
    /// The MPI job is not the launch the variables announce.
    #[error(
        "the launcher's variables ({variables}) say {launched} processes, but MPI gives this \
         process a job of {size}: start the processes with mpirun or srun (with MPI support), \
         or unset those variables to run one process"
    )]
    JobSize {
        /// The processes the launcher's variables announce.
        launched: usize,
        /// The processes of the MPI job.
        size: usize,
        /// The launcher's variables that are set, `NAME=VALUE` joined by commas.
        variables: String,
    },
    /// A stop request's handler could not be installed.
    #[error("cannot install the {signal} handler")]
    Handler {
        /// The request (`Ctrl-C`, `SIGUSR1`).
        signal: &'static str,
        /// Why.
        #[source]
        source: Box<dyn std::error::Error + Send + Sync>,
    },
    /// Anything else.
    #[error(transparent)]
    Run(#[from] TrainError),
}

impl From<LaunchError> for TrainError {
    /// A usage error becomes a configuration error, for the callers that
    /// have no usage errors of their own (the library, the tests); the
    /// launch's own errors become distributed ones.
    fn from(error: LaunchError) -> Self {
        match error {
            LaunchError::Usage(message) => TrainError::Config(message),
            LaunchError::Run(e) => e,
            other => TrainError::Distributed(other.to_string()),
        }
    }
}

/// How [`Launched::train`] ended.
#[derive(Debug)]
pub enum Ended {
    /// The run's checkpoints already held every step: nothing was trained.
    Complete {
        /// Steps its newest checkpoint holds.
        steps: usize,
        /// Steps of the whole run.
        total: usize,
    },
    /// Every step was taken.
    Finished {
        /// The last validation, if the data has ground truth.
        metrics: Option<Box<ValidationMetrics>>,
    },
    /// Stopped on request with a checkpoint.
    Stopped {
        /// Steps taken.
        steps: usize,
        /// Steps of the whole run.
        total: usize,
    },
}

impl Launched {
    /// Whether this process writes the run's folder and reports (rank 0 of
    /// several, or the process alone).
    pub fn is_writer(&self) -> bool {
        self.run.is_writer()
    }

    /// Whether the run's checkpoints already hold every step.
    pub fn is_complete(&self) -> bool {
        self.steps_complete().is_some()
    }

    /// The steps of the newest checkpoint, when it holds every step.
    fn steps_complete(&self) -> Option<usize> {
        match self.start {
            Start::Resumed(steps) if steps >= self.run.config().steps() => Some(steps),
            _ => None,
        }
    }

    /// Trains the run to its end, or until `stop` is set (see
    /// [`stop_requests`]); a complete run trains nothing. The writer
    /// reports to `observer`, the other ranks train quietly.
    pub fn train(
        mut self,
        observer: &mut dyn Observer,
        stop: &AtomicBool,
    ) -> Result<Ended, TrainError> {
        let total = self.run.config().steps();
        if let Some(steps) = self.steps_complete() {
            return Ok(Ended::Complete { steps, total });
        }
        let end = match self.run.is_writer() {
            true => self.run.run(observer, stop)?,
            false => self.run.run(&mut Quiet, stop)?,
        };
        Ok(match end {
            End::Finished { metrics } => Ended::Finished { metrics },
            End::Stopped(steps) => Ended::Stopped { steps, total },
        })
    }
}

impl TrainingRun {
    /// Opens the run in `out` on the training data of `manifest`, on the
    /// CPU, in this process alone (see [`Launch`] for the devices, the
    /// processes and the first weights): resumes from the newest
    /// checkpoint there, or starts fresh. Resuming with a configuration
    /// that changes what is computed is refused. This is the quiet entry
    /// of the library and the tests: like [`Launch::open`] it removes the
    /// temporary files a killed earlier run left in `out`, but it neither
    /// reports how many nor returns the launcher's warnings (the memory a
    /// step needs); a front end that shows them uses [`Launch`].
    pub fn open(
        manifest: &Path,
        out: &Path,
        config: RunConfig,
    ) -> Result<(Self, Start), TrainError> {
        let devices = "cpu".parse()?;
        let launch = Launch {
            manifest,
            out,
            config,
            devices: &devices,
            processes: None,
            beginning: Beginning::default(),
            reduction: None,
        };
        let launched = launch.open()?;
        Ok((launched.run, launched.start))
    }
}

impl Launch<'_> {
    /// Opens the run: the devices (under one consensus), the strategy for
    /// them, the inputs (manifest, `--init`), the data and the newest
    /// checkpoint; then one agreement of the ranks on the settings, the
    /// manifest's digest, the devices, `restart`, `init` and the
    /// checkpoint found; the first weights, checked equal on every rank;
    /// and last the writer's folder (the others wait for it).
    pub fn open(self) -> Result<Launched, LaunchError> {
        let processes = self.processes.as_deref();
        let (names, devices) = devices::open(self.devices, processes)?;
        let labelled = names.iter().map(ToString::to_string).zip(devices).collect();
        let strategy: Box<dyn Strategy<StereoNetwork>> = place(
            &self.config,
            labelled,
            self.processes.clone(),
            self.reduction.clone(),
        )
        .map_err(|e| match e {
            TrainError::Config(message) => LaunchError::Usage(message),
            other => other.into(),
        })?;
        let hold = open::hold_folder(self.out, strategy.writes());
        let hold = match processes {
            Some(processes) => all_succeeded(processes, hold)?,
            None => hold?,
        };
        let mut warnings = self.check_memory(&names, strategy.writes())?;
        self.check_inputs()?;
        self.config.validate()?;
        let (samples, validation) = open::load_data(self.manifest, &self.config)?;
        let Beginning { init, restart } = self.beginning;
        let latest = (!restart)
            .then(|| Checkpoint::latest(self.out))
            .transpose()?;
        let latest = latest.flatten();
        if let Some(processes) = processes {
            agree(processes, &self.identity(latest.as_ref())?)?;
        }
        let home = strategy.devices()[0].clone();
        let (trainer, start) = open::trainer(&self.config, &home, latest, init)?;
        strategy.check_same_weights(
            [trainer.student(), trainer.teacher()],
            trainer.steps_taken(),
        )?;
        let inputs = self.input_files()?;
        let folder = open::prepare_folder(self.out, hold, &inputs, &self.config, (start, restart));
        let folder = match processes {
            // The others wait until the writer has prepared the folder,
            // and share its outcome.
            Some(processes) => all_succeeded(processes, folder)?,
            None => folder?,
        };
        let removed_partials = folder.as_ref().map_or(0, |p| p.removed_partials);
        let folder = folder.map(|p| p.folder);
        warnings.extend(folder.as_ref().and_then(OutDir::lock_warning));
        let data = (samples, validation);
        let run = TrainingRun::assemble(self.out, self.config, data, trainer, strategy, start)
            .holding(folder);
        Ok(Launched {
            run,
            start,
            warnings,
            removed_partials,
        })
    }

    /// Checks the run on `names` (this process's devices) against this
    /// machine's memory ([`crate::memory::check`]): every rank checks its
    /// own machine, and a machine too small refuses the run on every rank
    /// alike (naming the rank, as a device that cannot be opened does).
    /// The warnings are the writer's (`writes`) to show; the others'
    /// machines warn nobody, as no one would read them.
    fn check_memory(&self, names: &[DeviceName], writes: bool) -> Result<Vec<String>, TrainError> {
        let checked = crate::memory::check(&self.config, names);
        let checked = match self.processes.as_deref() {
            None => checked?,
            Some(processes) => all_succeeded(processes, checked)?,
        };
        Ok(match writes {
            true => checked.into_iter().collect(),
            false => Vec::new(),
        })
    }

    /// Refuses a manifest that is not a file, and an `init` that does not
    /// exist or that `restart` would remove: the run's own folder or one
    /// of its checkpoints.
    fn check_inputs(&self) -> Result<(), TrainError> {
        if let Some(message) = mbs_core::regular::not_a_file(self.manifest, "manifest") {
            return Err(TrainError::Input(message));
        }
        let Some(init) = self.beginning.init else {
            return Ok(());
        };
        if !init.exists() {
            let shown = init.display();
            return Err(TrainError::Input(format!(
                "--init {shown}: no such file or folder"
            )));
        }
        let inside = |a: &Path, b: &Path| match (a.canonicalize(), b.canonicalize()) {
            (Ok(a), Ok(b)) => a.starts_with(b),
            _ => false,
        };
        let out = self.out;
        if self.beginning.restart && (inside(init, &out.join(CHECKPOINTS_DIR)) || inside(out, init))
        {
            return Err(TrainError::Input(format!(
                "--init {}: --restart removes the checkpoints of {} that it would start from; \
                 copy them elsewhere first, or resume without --restart",
                init.display(),
                out.display()
            )));
        }
        Ok(())
    }

    /// Every file the run reads: the manifest, every file of its samples,
    /// and the files of `init` (a weights file, or the newest checkpoint's
    /// files of a run or checkpoint folder).
    fn input_files(&self) -> Result<InputFiles, TrainError> {
        let mut inputs = InputFiles::new();
        inputs.add(self.manifest);
        let manifest = mbs_dataset::Manifest::load(self.manifest)?;
        inputs.extend(mbs_dataset::pairs::manifest_files(self.manifest, &manifest));
        if let Some(init) = self.beginning.init {
            inputs.extend(TrainedNetworks::files_read_from(init));
        }
        Ok(inputs)
    }

    /// What every rank must hold alike: the settings, the manifest's
    /// digest, the devices as listed, `restart`, `init` and the steps of
    /// the checkpoint it found.
    fn identity(&self, latest: Option<&Checkpoint>) -> Result<serde_json::Value, TrainError> {
        let manifest = self.manifest;
        let digest = mbs_dataset::checksum::sha256_file(manifest)
            .map_err(|e| TrainError::data(manifest, e))?;
        Ok(serde_json::json!({
            "settings": self.config.to_json()?,
            "manifest_sha256": digest,
            "device": self.devices.to_string(),
            "restart": self.beginning.restart,
            "init": self.beginning.init.map(|p| p.display().to_string()),
            "checkpoint": latest.map(|c| c.state.steps),
        }))
    }
}
