//! Pictures for people: disparity colour maps, contact sheets, the S3
//! weight map and line charts of training curves, as `image` RGB buffers
//! or PNG files.

pub mod chart;
pub mod colormap;
pub mod error;
pub mod sheet;
pub mod weight_map;

pub use chart::{LineChart, Series};
pub use colormap::{colorize_disparity, disparity_scale, turbo};
pub use error::VizError;
pub use sheet::{extrapolation_sheet, side_by_side};
pub use weight_map::weight_map_image;
