//! NGSIM I-80 naturalistic data: loading both official layouts (feet to metres at the
//! boundary) and Savitzky-Golay smoothing of the positions.

pub mod load;
pub mod smooth;
