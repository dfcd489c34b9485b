//! Savitzky-Golay smoothing (least-squares polynomial of order `order` over a sliding window of
//! `window` samples, `window` odd). Interior samples take the fitted value at the window's
//! centre; the first and last `window / 2` samples take the values of the polynomial fitted to
//! the first and the last window, as MATLAB's `sgolayfilt` and scipy's `savgol_filter(...,
//! mode="interp")` do. A series shorter than the window is returned unchanged (the paper leaves
//! such series unsmoothed).

use nalgebra::DMatrix;

/// Errors in the filter parameters.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SmoothError {
    /// The window must be odd and larger than the order.
    #[error("Savitzky-Golay window {window} must be odd and larger than the polynomial order {order}")]
    Parameters {
        /// Window length.
        window: usize,
        /// Polynomial order.
        order: usize,
    },
}

/// The hat matrix `A (A^T A)^-1 A^T` of a window: row `k` maps the window's samples to the
/// fitted polynomial's value at position `k`.
fn hat_matrix(window: usize, order: usize) -> DMatrix<f64> {
    let half = (window / 2) as f64;
    // Centred positions keep the normal equations well conditioned.
    let a = DMatrix::from_fn(window, order + 1, |i, j| (i as f64 - half).powi(j as i32));
    let ata = a.transpose() * &a;
    let inv = ata
        .try_inverse()
        .expect("a Vandermonde matrix with distinct nodes has full rank");
    &a * inv * a.transpose()
}

/// Smooths `y` with a Savitzky-Golay filter (see the module docs).
pub fn savgol(y: &[f64], window: usize, order: usize) -> Result<Vec<f64>, SmoothError> {
    if window % 2 == 0 || window <= order {
        return Err(SmoothError::Parameters { window, order });
    }
    let n = y.len();
    if n < window {
        return Ok(y.to_vec());
    }
    let h = hat_matrix(window, order);
    let half = window / 2;
    let fit = |row: usize, start: usize| (0..window).map(|j| h[(row, j)] * y[start + j]).sum::<f64>();
    let mut out = vec![0.0; n];
    for (i, o) in out.iter_mut().enumerate() {
        *o = if i < half {
            fit(i, 0)
        } else if i >= n - half {
            fit(window - (n - i), n - window)
        } else {
            fit(half, i - half)
        };
    }
    Ok(out)
}

/// Smooths a recorded series piece by piece: a gap in the frames (consecutive frames more than
/// one apart: the vehicle left the cameras' view, or the data has a hole) splits it, and each
/// piece is filtered on its own (a piece shorter than the window stays as recorded). Across a
/// gap the filter would blend positions seconds apart: the real I-80 sample has three such
/// vehicles, one with a 8.7 s hole.
pub fn savgol_segments(
    frames: &[u32],
    y: &[f64],
    window: usize,
    order: usize,
) -> Result<Vec<f64>, SmoothError> {
    assert_eq!(frames.len(), y.len(), "one frame per value");
    let mut out = Vec::with_capacity(y.len());
    let mut start = 0;
    for i in 1..=y.len() {
        if i == y.len() || frames[i - 1].checked_add(1) != Some(frames[i]) {
            out.extend(savgol(&y[start..i], window, order)?);
            start = i;
        }
    }
    Ok(out)
}
