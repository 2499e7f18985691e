//! The S3 loss (paper eq. 7):
//! `L = mean(A |d_s - r d_t|) + lambda_p mean(M_s P_s) + lambda_s L_s`,
//! with a switch for every term and every mask part (paper Tables 3 and 4),
//! plus `lambda_r` times the range term, zero for any plausible prediction,
//! `lambda_v` times the view term, zero where every warp lands in the
//! target (both in [`range`]), and masks that count warps leaving the
//! target as invalid ([`LossConfig::out_of_view_invalid`]); `range_weight =
//! 0` and `out_of_view_invalid = false` are the paper's loss exactly (the
//! view term is off by default).

pub mod geometry;
pub mod photometric;
pub mod range;
pub mod smoothness;
pub mod terms;
pub mod warp;

use burn::config::Config;
use burn::tensor::Tensor;
use mbs_core::geometry::Side;

use crate::error::TrainError;
use crate::mask::{MaskParts, validity_mask, weight_map};
use geometry::{ScaleMatch, geometry_consistency};
use mbs_nets::ranges;
use photometric::photometric_map;
use range::{out_of_range, out_of_view};
use smoothness::edge_aware_smoothness;
pub use terms::{Term, Terms};
use warp::{lands_inside, warp_to_reference};

/// Hyper-parameters and ablation switches of the S3 loss; the defaults are
/// the paper's but for the two safeguards `range_weight` and
/// `out_of_view_invalid` (docs/training.md, "S3 from random weights").
#[derive(Config, Debug, PartialEq)]
pub struct LossConfig {
    /// Photometric threshold `tau` of the validity masks.
    #[config(default = 0.1)]
    pub tau: f64,
    /// Weight `omega` of pixels the teacher sees and the student does not.
    #[config(default = 2.0)]
    pub omega: f64,
    /// Weight `lambda_p` of the photometric term.
    #[config(default = 10.0)]
    pub lambda_p: f64,
    /// `lambda_s / lambda_p` (the paper sets `lambda_s = 0.001 lambda_p`).
    #[config(default = 0.001)]
    pub lambda_s_ratio: f64,
    /// SSIM share `alpha` of the photometric error.
    #[config(default = 0.85)]
    pub alpha: f64,
    /// Side of the SSIM box window (odd): 7 as the authors' toolbox, 3 as monodepth2.
    #[config(default = 7)]
    pub ssim_window: usize,
    /// Geometry-consistency term `L_g` on (Table 3).
    #[config(default = true)]
    pub geometry: bool,
    /// Photometric term `L_p` on (Table 3).
    #[config(default = true)]
    pub photometric: bool,
    /// Smoothness term `L_s` on (Table 3).
    #[config(default = true)]
    pub smoothness: bool,
    /// Photometric threshold filtering `P < tau` in the masks (PTF, Table 4).
    #[config(default = true)]
    pub threshold_filter: bool,
    /// Auto-masking `P < P_identity` in the masks (AMF, Table 4).
    #[config(default = true)]
    pub auto_mask: bool,
    /// Occlusion-aware enhancement: weight `omega` instead of 1 where only
    /// the teacher sees (OAE, Table 4).
    #[config(default = true)]
    pub occlusion_enhancement: bool,
    /// Divide each disparity map by its mean in the smoothness term, as
    /// monodepth2; off as the paper's eq. 3.
    #[config(default = false)]
    pub normalise_smoothness: bool,
    /// Largest target `r d_t` (pixels) the geometry term supervises; 0
    /// supervises every pixel. Wide MBS20K pairs reach `d = 960 / z` px at
    /// a 2 m baseline, beyond a cost volume's range: set it to the
    /// network's range (`network.max_disparity`) for such backbones.
    #[config(default = 0.0)]
    pub max_target_disparity: f64,
    /// Weight `lambda_r` of the range term, the mean distance (px) of the
    /// student's disparities outside `[0, W - 1]`: zero for plausible
    /// predictions, a way back for a network whose disparities have left
    /// the image (where the paper's terms lose their gradient and training
    /// collapses). 0 is the paper's loss.
    #[config(default = 1.0)]
    pub range_weight: f64,
    /// Weight `lambda_v` of the view term, the mean distance (px) by which
    /// the student's warps land outside the target image
    /// ([`range::out_of_view`]): a way back for disparities that are
    /// plausible for the image's width but too large for the pixel's
    /// column, where the clamped warp has no gradient. 0 is the paper's
    /// loss; training runs of IGEV-Stereo default to 0.1
    /// ([`crate::RunConfig::backbone_defaults`]).
    #[config(default = 0.0)]
    pub view_weight: f64,
    /// Rescale each item's geometry target `r d_t` to the student's
    /// weighted mean before comparing ([`geometry::match_scale`]), so the
    /// geometry term supervises the shape of the disparities and the
    /// photometric term their scale; `false` (the default) is the paper's
    /// term. It stops a runaway of the disparities' scale; training runs of
    /// RAFT-Stereo and IGEV-Stereo default to `true`
    /// ([`crate::RunConfig::backbone_defaults`]; docs/training.md, "S3 from random
    /// weights").
    #[config(default = false)]
    pub geometry_scale_match: bool,
    /// With [`LossConfig::geometry_scale_match`], rescale the target to
    /// the scale at which the L1 term has no net pull on the student's
    /// scale (a weighted median of the per-pixel ratios,
    /// [`geometry::match_scale_neutral`]) instead of to equal means, which
    /// leave a pull toward the teacher's median; `false` (the default)
    /// keeps the means.
    #[config(default = false)]
    pub geometry_scale_neutral: bool,
    /// Count pixels whose warp leaves the target image as invalid in both
    /// masks. The warp clamps to the border column there, and a border
    /// that happens to resemble the reference pixel would pass the paper's
    /// tests (`P < tau`, `P < P_identity`): such false matches let a
    /// teacher whose disparities are far too large supervise the student,
    /// which then grows its own (docs/training.md, "S3 from random weights"). The
    /// paper leaves this open (PyTorch's `grid_sample` pads with zeros,
    /// which mostly fails the tests); `false` keeps the border's verdict.
    #[config(default = true)]
    pub out_of_view_invalid: bool,
    /// Average the photometric term over the student's mask `M_s` (its
    /// weights, with [`LossConfig::outside_mask_weight`]) instead of over
    /// every pixel. The paper's `L_p * M_s` leaves the reduction
    /// open; over every pixel (`false`, the default) the term shrinks with
    /// the student's mask, while the geometry term's weight `A` grows
    /// (`omega` instead of 1 where the student's mask has lost a pixel the
    /// teacher's keeps).
    #[config(default = false)]
    pub photometric_mask_mean: bool,
    /// Weight of the photometric error at pixels the student's mask leaves
    /// out (0 is the paper's `M_s P_s`). The mask depends on the student's
    /// own prediction, and a pixel it drops has no photometric gradient to
    /// bring it back; a small weight keeps one (0.1 for training runs of
    /// RAFT-Stereo and IGEV-Stereo, [`crate::RunConfig::backbone_defaults`]).
    #[config(default = 0.0)]
    pub outside_mask_weight: f64,
}

impl LossConfig {
    /// Smoothness weight `lambda_s = lambda_s_ratio * lambda_p`.
    pub fn lambda_s(&self) -> f64 {
        self.lambda_s_ratio * self.lambda_p
    }

    /// How the geometry target is rescaled to the student's scale.
    pub fn scale_match(&self) -> ScaleMatch {
        match (self.geometry_scale_match, self.geometry_scale_neutral) {
            (false, _) => ScaleMatch::Off,
            (true, false) => ScaleMatch::Mean,
            (true, true) => ScaleMatch::Neutral,
        }
    }

    /// The mask parts switched on.
    pub fn mask_parts(&self) -> MaskParts {
        MaskParts {
            threshold: self.threshold_filter.then_some(self.tau),
            auto_mask: self.auto_mask,
        }
    }

    /// The effective `omega` (1 when occlusion-aware enhancement is off).
    pub fn effective_omega(&self) -> f64 {
        if self.occlusion_enhancement {
            self.omega
        } else {
            1.0
        }
    }

    /// Checks every value against its valid range.
    pub fn validate(&self) -> Result<(), TrainError> {
        ranges::positive("tau", self.tau)?;
        ranges::non_negative("omega", self.omega)?;
        ranges::non_negative("lambda_p", self.lambda_p)?;
        ranges::non_negative("lambda_s_ratio", self.lambda_s_ratio)?;
        ranges::unit("alpha", self.alpha)?;
        ranges::non_negative("max_target_disparity", self.max_target_disparity)?;
        ranges::non_negative("range_weight", self.range_weight)?;
        ranges::non_negative("view_weight", self.view_weight)?;
        ranges::unit("outside_mask_weight", self.outside_mask_weight)?;
        ranges::require(
            self.ssim_window % 2 == 1,
            "ssim_window",
            self.ssim_window,
            "an odd window side such as 3 or 7",
        )?;
        ranges::require(
            self.geometry || self.photometric || self.smoothness,
            "geometry/photometric/smoothness",
            "all false",
            "at least one loss term on",
        )?;
        Ok(())
    }
}

/// One batch of what the loss sees. Images are `[B, C, H, W]` in `[0, 1]`,
/// clean (un-augmented: masks and photometric maps use clean images, also
/// for the student); disparities are `[B, 1, H, W]` on the reference grid,
/// already mirrored back for left targets.
#[derive(Debug, Clone)]
pub struct LossInputs {
    /// Reference images `I_r`.
    pub reference: Tensor<4>,
    /// The student's target images `I_ts`.
    pub student_target: Tensor<4>,
    /// The teacher's target images `I_tt`.
    pub teacher_target: Tensor<4>,
    /// Student prediction `d_s` (carries the gradient).
    pub student_disparity: Tensor<4>,
    /// Teacher prediction `d_t` (detached by the loss).
    pub teacher_disparity: Tensor<4>,
    /// Side of each student target relative to its reference.
    pub student_sides: Vec<Side>,
    /// Side of each teacher target relative to its reference.
    pub teacher_sides: Vec<Side>,
    /// Baseline ratio `r = B_s / B_t` of each batch item.
    pub ratios: Vec<f64>,
    /// The weight of the geometry term at this step: 1 as the paper, 0
    /// before the trainer's geometry start and less during its warm-up
    /// ([`crate::step::TrainerConfig::geometry_start`]).
    pub geometry_weight: f64,
}

/// The loss and its parts. Terms that are switched off are `None`.
#[derive(Debug, Clone)]
pub struct LossOutput {
    /// The weighted total `L`, differentiable in the student disparity.
    pub total: Tensor<1>,
    /// Each term before its weight (the photometric one with `M_s`
    /// weighted and the mean taken as [`LossConfig::outside_mask_weight`]
    /// and [`LossConfig::photometric_mask_mean`] say); the range and view
    /// terms are off when their weights are 0.
    pub terms: Terms<Tensor<1>>,
    /// Student validity mask `M_s` (0/1), when the photometric or geometry term is on.
    pub student_mask: Option<Tensor<4>>,
    /// Teacher validity mask `M_t` (0/1), when the geometry term is on.
    pub teacher_mask: Option<Tensor<4>>,
    /// Occlusion-aware weight map `A`, when the geometry term is on.
    pub weight_map: Option<Tensor<4>>,
}

/// The S3 loss with a validated configuration.
#[derive(Debug, Clone)]
pub struct S3Loss {
    config: LossConfig,
}

impl LossOutput {
    /// The value of `term`, when it is on.
    pub fn term(&self, term: Term) -> Option<Tensor<1>> {
        self.terms.get(term).cloned()
    }
}

impl S3Loss {
    /// A loss from a configuration, checked by [`LossConfig::validate`].
    pub fn new(config: LossConfig) -> Result<Self, TrainError> {
        config.validate()?;
        Ok(Self { config })
    }

    /// The configuration in use.
    pub fn config(&self) -> &LossConfig {
        &self.config
    }

    /// Photometric map `P(I_r, I_tgt)` of a target against the reference:
    /// the un-warped target (the identity map of auto-masking) or, with a
    /// disparity, the target warped to the reference.
    fn photometric(
        &self,
        reference: &Tensor<4>,
        target: Tensor<4>,
        warp: Option<(Tensor<4>, &[Side])>,
    ) -> Tensor<4> {
        let target = match warp {
            Some((disparity, sides)) => warp_to_reference(target, disparity, sides),
            None => target,
        };
        photometric_map(
            reference.clone(),
            target,
            self.config.alpha,
            self.config.ssim_window,
        )
    }

    /// `mask` without the pixels whose warp by `disparity` leaves the
    /// target, when [`LossConfig::out_of_view_invalid`] is on.
    fn in_view(&self, mask: Tensor<4>, disparity: Tensor<4>, sides: &[Side]) -> Tensor<4> {
        match self.config.out_of_view_invalid {
            true => mask * lands_inside(disparity, sides),
            false => mask,
        }
    }

    /// Computes `L` and its parts for one batch.
    pub fn compute(&self, inputs: LossInputs) -> Result<LossOutput, TrainError> {
        self.compute_sequence(inputs, Vec::new())
    }

    /// Computes `L` and its parts for the final student prediction of
    /// `inputs`, and adds to the total `weight * L` of each `earlier`
    /// prediction of an iterative student (same shape). What does not
    /// depend on the student's prediction (the teacher's mask and the
    /// identity maps) is computed once.
    pub fn compute_sequence(
        &self,
        inputs: LossInputs,
        earlier: Vec<(Tensor<4>, f64)>,
    ) -> Result<LossOutput, TrainError> {
        check_shapes(&inputs, self.config.ssim_window)?;
        let want = inputs.student_disparity.dims();
        if let Some((other, _)) = earlier.iter().find(|(d, _)| d.dims() != want) {
            return Err(TrainError::Shape(format!(
                "an earlier student prediction is {:?}, expected {want:?}",
                other.dims()
            )));
        }
        let shared = self.shared(&inputs);
        let mut out = self.terms(&inputs, &shared, inputs.student_disparity.clone());
        for (disparity, weight) in earlier {
            let terms = self.terms(&inputs, &shared, disparity);
            out.total = out.total + terms.total * weight;
        }
        Ok(out)
    }

    /// The parts of the loss that do not depend on the student's prediction.
    fn shared(&self, inputs: &LossInputs) -> Shared {
        let config = &self.config;
        let needs_mask = config.photometric || config.geometry;
        let student_identity = needs_mask
            .then(|| self.photometric(&inputs.reference, inputs.student_target.clone(), None));
        let teacher = config.geometry.then(|| {
            let disparity = inputs.teacher_disparity.clone().detach();
            let warped = self.photometric(
                &inputs.reference,
                inputs.teacher_target.clone(),
                Some((disparity.clone(), &inputs.teacher_sides)),
            );
            let identity = self.photometric(&inputs.reference, inputs.teacher_target.clone(), None);
            let mask = validity_mask(warped, identity, config.mask_parts());
            (
                self.in_view(mask, disparity.clone(), &inputs.teacher_sides),
                disparity,
            )
        });
        Shared {
            student_identity,
            teacher,
        }
    }

    /// `L` and its parts for one student prediction.
    fn terms(&self, inputs: &LossInputs, shared: &Shared, student: Tensor<4>) -> LossOutput {
        let config = &self.config;
        let mut total = Tensor::<1>::zeros([1], &student.device());
        let mut out = LossOutput {
            total: total.clone(),
            terms: Terms::default(),
            student_mask: None,
            teacher_mask: None,
            weight_map: None,
        };
        if let Some(identity) = &shared.student_identity {
            total = self.masked_terms(inputs, shared, identity, &student, &mut out, total);
        }
        if config.range_weight > 0.0 {
            let term = out_of_range(student.clone());
            total = total + term.clone() * config.range_weight;
            out.terms.set(Term::Range, term);
        }
        if config.view_weight > 0.0 {
            let term = out_of_view(student.clone(), &inputs.student_sides);
            total = total + term.clone() * config.view_weight;
            out.terms.set(Term::View, term);
        }
        if config.smoothness {
            let term = edge_aware_smoothness(
                student,
                inputs.reference.clone(),
                config.normalise_smoothness,
            );
            total = total + term.clone() * config.lambda_s();
            out.terms.set(Term::Smoothness, term);
        }
        out.total = total;
        out
    }

    /// Adds to `total` the terms that need the student's validity mask
    /// `M_s` (`identity`: the student pair's identity photometric map): the
    /// photometric term and, with the teacher's mask in `shared`, the
    /// geometry term; records them and the masks in `out`.
    fn masked_terms(
        &self,
        inputs: &LossInputs,
        shared: &Shared,
        identity: &Tensor<4>,
        student: &Tensor<4>,
        out: &mut LossOutput,
        mut total: Tensor<1>,
    ) -> Tensor<1> {
        let config = &self.config;
        let p_s = self.photometric(
            &inputs.reference,
            inputs.student_target.clone(),
            Some((student.clone(), &inputs.student_sides)),
        );
        let m_s = validity_mask(p_s.clone(), identity.clone(), config.mask_parts());
        let m_s = self.in_view(m_s, student.clone(), &inputs.student_sides);
        if config.photometric {
            let beta = config.outside_mask_weight;
            let weights = m_s.clone() * (1.0 - beta) + beta;
            let masked = weights.clone() * p_s;
            let term = match config.photometric_mask_mean {
                true => masked.sum() / weights.sum().clamp_min(1.0),
                false => masked.mean(),
            };
            total = total + term.clone() * config.lambda_p;
            out.terms.set(Term::Photometric, term);
        }
        if let Some((m_t, teacher_disparity)) = &shared.teacher {
            let a = weight_map(m_t.clone(), m_s.clone(), config.effective_omega());
            let term = geometry_consistency(
                student.clone(),
                teacher_disparity.clone(),
                &inputs.ratios,
                a.clone(),
                (config.max_target_disparity > 0.0).then_some(config.max_target_disparity),
                config.scale_match(),
            );
            total = total + term.clone() * inputs.geometry_weight;
            out.terms.set(Term::Geometry, term);
            out.teacher_mask = Some(m_t.clone());
            out.weight_map = Some(a);
        }
        out.student_mask = Some(m_s);
        total
    }
}

/// What every student prediction's loss shares: the identity photometric
/// map of the student's pair (when a mask is needed) and the teacher's
/// validity mask with its detached disparity (when the geometry term is on).
struct Shared {
    student_identity: Option<Tensor<4>>,
    teacher: Option<(Tensor<4>, Tensor<4>)>,
}

/// Checks the shapes the loss relies on.
fn check_shapes(inputs: &LossInputs, window: usize) -> Result<(), TrainError> {
    let [batch, channels, height, width] = inputs.reference.dims();
    let image = [batch, channels, height, width];
    let map = [batch, 1, height, width];
    let named = [
        ("student target", inputs.student_target.dims(), image),
        ("teacher target", inputs.teacher_target.dims(), image),
        ("student disparity", inputs.student_disparity.dims(), map),
        ("teacher disparity", inputs.teacher_disparity.dims(), map),
    ];
    for (name, got, want) in named {
        if got != want {
            return Err(TrainError::Shape(format!(
                "{name} is {got:?}, expected {want:?}"
            )));
        }
    }
    for (name, len) in [
        ("student sides", inputs.student_sides.len()),
        ("teacher sides", inputs.teacher_sides.len()),
        ("ratios", inputs.ratios.len()),
    ] {
        if len != batch {
            return Err(TrainError::Shape(format!(
                "{len} {name} for a batch of {batch}"
            )));
        }
    }
    if width < 2 || window / 2 >= height.min(width) {
        return Err(TrainError::Shape(format!(
            "images of {height}x{width} are too small for a {window}x{window} SSIM window"
        )));
    }
    Ok(())
}

#[cfg(test)]
mod tests;
