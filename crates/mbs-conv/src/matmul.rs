//! Matrix products through `gemm`, on strided views of slices.

/// A read-only matrix view: element `(i, j)` is
/// `data[i * row_stride + j * column_stride]`.
#[derive(Debug, Clone, Copy)]
pub struct Matrix<'a> {
    data: &'a [f32],
    rows: usize,
    columns: usize,
    row_stride: usize,
    column_stride: usize,
}

impl<'a> Matrix<'a> {
    /// `data` as a row-major matrix of rows of `columns` values.
    pub fn rows(data: &'a [f32], columns: usize) -> Self {
        Self::strided(data, data.len() / columns.max(1), columns, columns)
    }

    /// `rows` rows of `columns` values, each `row_stride` after the last.
    pub fn strided(data: &'a [f32], rows: usize, columns: usize, row_stride: usize) -> Self {
        Self {
            data,
            rows,
            columns,
            row_stride,
            column_stride: 1,
        }
    }

    /// The transpose (a view of the same values).
    pub fn transposed(self) -> Self {
        Self {
            rows: self.columns,
            columns: self.rows,
            row_stride: self.column_stride,
            column_stride: self.row_stride,
            ..self
        }
    }

    /// Whether every element lies inside `data`.
    fn fits(&self) -> bool {
        self.rows == 0
            || self.columns == 0
            || (self.rows - 1) * self.row_stride + (self.columns - 1) * self.column_stride
                < self.data.len()
    }
}

/// Products smaller than this (in multiply-adds) run on one thread.
const PARALLEL_FROM: usize = 1 << 18;

/// `dst = lhs x rhs`, or `dst += lhs x rhs` when `accumulate`; `dst` is
/// row-major with rows `dst_row_stride` apart, `lhs.rows` by `rhs.columns`.
/// A large product runs on rayon's threads when `parallel` (not when the
/// caller already runs several at once).
///
/// # Panics
///
/// When the shapes do not chain or a view reaches past its slice.
pub fn matmul(
    dst: &mut [f32],
    dst_row_stride: usize,
    lhs: Matrix,
    rhs: Matrix,
    accumulate: bool,
    parallel: bool,
) {
    let (m, k, n) = (lhs.rows, lhs.columns, rhs.columns);
    assert_eq!(k, rhs.rows, "matmul: inner dimensions differ");
    assert!(
        lhs.fits() && rhs.fits(),
        "matmul: a view reaches past its slice"
    );
    if m == 0 || n == 0 {
        return;
    }
    assert!(
        (m - 1) * dst_row_stride + n <= dst.len(),
        "matmul: the destination is too short"
    );
    if k == 0 {
        // An empty sum: zero, or nothing to add.
        if !accumulate {
            zero_rows(dst, dst_row_stride, m, n);
        }
        return;
    }
    let parallelism = parallelism(parallel, m * n * k);
    let stride = |s: usize| s as isize;
    // SAFETY: the assertions above keep every element gemm reads inside
    // `lhs.data` and `rhs.data` and every one it writes inside `dst`
    // (element (i, j) at i * stride + j * stride for i < rows, j <
    // columns); `dst` is borrowed mutably, so it overlaps neither input.
    #[allow(unsafe_code)]
    unsafe {
        gemm::gemm(
            m,
            n,
            k,
            dst.as_mut_ptr(),
            1,
            stride(dst_row_stride),
            accumulate,
            lhs.data.as_ptr(),
            stride(lhs.column_stride),
            stride(lhs.row_stride),
            rhs.data.as_ptr(),
            stride(rhs.column_stride),
            stride(rhs.row_stride),
            1.0f32,
            1.0f32,
            false,
            false,
            false,
            parallelism,
        );
    }
}

/// How gemm runs a product of `work` multiply-adds: on rayon's threads
/// when `parallel` and the product is large enough to gain from them.
fn parallelism(parallel: bool, work: usize) -> gemm::Parallelism {
    match parallel && work >= PARALLEL_FROM {
        true => gemm::Parallelism::Rayon(0),
        false => gemm::Parallelism::None,
    }
}

/// Sets the first `columns` values of `rows` rows of `dst`, `row_stride`
/// apart, to zero.
fn zero_rows(dst: &mut [f32], row_stride: usize, rows: usize, columns: usize) {
    for row in 0..rows {
        dst[row * row_stride..row * row_stride + columns].fill(0.0);
    }
}
