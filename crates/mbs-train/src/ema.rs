//! EMA teacher: `theta_t <- m theta_t + (1 - m) theta_s`, reading the
//! student with a [`ModuleVisitor`] and updating the teacher with a
//! [`ModuleMapper`].

use burn::module::{Module, ModuleMapper, ModuleVisitor, Param};
use burn::tensor::Tensor;

use crate::error::TrainError;
use mbs_nets::ranges;

/// Collects the student's float parameters, flattened, in visiting order.
struct StudentReader {
    values: Vec<Tensor<1>>,
}

impl ModuleVisitor for StudentReader {
    fn visit_float<const D: usize>(&mut self, param: &Param<Tensor<D>>) {
        let value = param.val().detach().without_autodiff();
        let numel = value.shape().num_elements();
        self.values.push(value.reshape([numel]));
    }
}

/// Blends each teacher parameter with the student parameter at the same
/// position in visiting order (teacher and student share one structure).
struct TeacherUpdater {
    student: std::vec::IntoIter<Tensor<1>>,
    momentum: f64,
    mismatch: Option<String>,
}

impl ModuleMapper for TeacherUpdater {
    fn map_float<const D: usize>(&mut self, param: Param<Tensor<D>>) -> Param<Tensor<D>> {
        let Some(student) = self.student.next() else {
            self.mismatch
                .get_or_insert_with(|| "the teacher has more parameters than the student".into());
            return param;
        };
        let momentum = self.momentum;
        let mut mismatch = None;
        let param = param.map(|teacher| {
            let dims = teacher.dims();
            let numel = teacher.shape().num_elements();
            if student.dims()[0] != numel {
                mismatch = Some(format!(
                    "a parameter of {numel} values meets one of {}",
                    student.dims()[0]
                ));
                return teacher;
            }
            let teacher_device = teacher.device();
            let student = student.reshape(dims);
            // Keep the teacher off the autodiff graph: it never takes a gradient.
            let student = if teacher_device.is_autodiff() {
                student.autodiff()
            } else {
                student
            };
            (teacher * momentum + student * (1.0 - momentum)).detach()
        });
        if let Some(message) = mismatch {
            self.mismatch.get_or_insert(message);
        }
        param
    }
}

/// One EMA step: returns the teacher with every float parameter replaced by
/// `momentum * teacher + (1 - momentum) * student`. The teacher is usually
/// `student.valid()` (no autodiff); the student may be on an autodiff device.
pub fn ema_update<M: Module>(teacher: M, student: &M, momentum: f64) -> Result<M, TrainError> {
    ranges::unit("momentum", momentum)?;
    let mut reader = StudentReader { values: Vec::new() };
    student.visit(&mut reader);
    let mut updater = TeacherUpdater {
        student: reader.values.into_iter(),
        momentum,
        mismatch: None,
    };
    let teacher = teacher.map(&mut updater);
    if updater.student.next().is_some() {
        updater
            .mismatch
            .get_or_insert_with(|| "the student has more parameters than the teacher".into());
    }
    match updater.mismatch {
        Some(message) => Err(TrainError::Shape(format!(
            "EMA teacher and student differ: {message}"
        ))),
        None => Ok(teacher),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use burn::nn::{Linear, LinearConfig};
    use burn::tensor::{Device, TensorData};
    use mbs_nets::test_util::{assert_close, values};

    fn linear(weight: &[f32], bias: &[f32], device: &Device) -> Linear {
        let weight = Tensor::<2>::from_data(TensorData::new(weight.to_vec(), [2, 2]), device);
        let bias = Tensor::<1>::from_data(TensorData::new(bias.to_vec(), [2]), device);
        Linear {
            weight: Param::from_tensor(weight),
            bias: Some(Param::from_tensor(bias)),
        }
    }

    #[test]
    fn update_moves_parameters_by_the_exact_amount() {
        let device = Device::flex();
        let teacher = linear(&[1.0, 2.0, 3.0, 4.0], &[0.0, 1.0], &device);
        let student = linear(&[3.0, 2.0, 1.0, 0.0], &[2.0, -1.0], &device);
        let teacher = ema_update(teacher, &student, 0.75).expect("same structure");
        // 0.75 t + 0.25 s.
        assert_close(&values(teacher.weight.val()), &[1.5, 2.0, 2.5, 3.0], 1e-6);
        assert_close(
            &values(teacher.bias.expect("bias on").val()),
            &[0.5, 0.5],
            1e-6,
        );
    }

    #[test]
    fn autodiff_student_updates_a_plain_teacher() {
        let device = Device::flex().autodiff();
        let student = LinearConfig::new(2, 2).init(&device);
        let teacher = student.valid();
        let moved = student.clone().map(&mut Shift);
        // momentum 0: the teacher becomes the (shifted) student, without autodiff.
        let teacher = ema_update(teacher, &moved, 0.0).expect("same structure");
        assert!(!teacher.weight.val().is_autodiff());
        let want = values(moved.weight.val().without_autodiff());
        assert_close(&values(teacher.weight.val()), &want, 1e-6);
    }

    #[test]
    fn rejects_a_different_structure_and_bad_momentum() {
        let device = Device::flex();
        let small = LinearConfig::new(2, 2).init(&device);
        let large = LinearConfig::new(2, 3).init(&device);
        assert!(matches!(
            ema_update(small.clone(), &large, 0.9),
            Err(TrainError::Shape(_))
        ));
        assert!(ema_update(small.clone(), &small, 1.5).is_err());
    }

    /// Adds 1 to every float parameter.
    struct Shift;
    impl ModuleMapper for Shift {
        fn map_float<const D: usize>(&mut self, param: Param<Tensor<D>>) -> Param<Tensor<D>> {
            param.map(|t| t + 1.0)
        }
    }
}
