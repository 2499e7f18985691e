//! Filling invalid disparities from the background side: a disoccluded or
//! unknown pixel takes the disparity of the farther (smaller-disparity)
//! surface next to it.

/// Fills each run of invalid (non-finite) values of one image row with the
/// smaller of the valid values on its two sides (the only one where the run
/// touches a border). A row without any valid value stays as it is.
pub fn fill_row_from_background(row: &mut [f32]) {
    let w = row.len();
    let mut x = 0;
    while x < w {
        if row[x].is_finite() {
            x += 1;
            continue;
        }
        let start = x;
        while x < w && !row[x].is_finite() {
            x += 1;
        }
        let left = start.checked_sub(1).map(|l| row[l]);
        let right = (x < w).then(|| row[x]);
        let value = match (left, right) {
            (Some(l), Some(r)) => l.min(r),
            (Some(v), None) | (None, Some(v)) => v,
            (None, None) => continue,
        };
        row[start..x].fill(value);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const INF: f32 = f32::INFINITY;

    #[test]
    fn runs_take_the_background_side_and_borders_the_neighbour() {
        let mut row = vec![INF, 5.0, INF, INF, 2.0, INF, 9.0, INF];
        fill_row_from_background(&mut row);
        assert_eq!(row, vec![5.0, 5.0, 2.0, 2.0, 2.0, 2.0, 9.0, 9.0]);
        let mut empty = vec![INF; 3];
        fill_row_from_background(&mut empty);
        assert!(empty.iter().all(|v| v.is_infinite()));
        let mut nothing: Vec<f32> = Vec::new();
        fill_row_from_background(&mut nothing);
    }
}
