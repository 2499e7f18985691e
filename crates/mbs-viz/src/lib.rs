//! Pictures for people: disparity colour maps, contact sheets with
//! captions and colour keys, the S3 weight map and line charts of training
//! curves, as `image` RGB buffers or PNG files.

pub mod chart;
pub mod colormap;
pub mod error;
pub mod labelled;
pub mod sheet;
mod text;
pub mod weight_map;

pub use chart::{LineChart, Series};
pub use colormap::{colorize_disparity, disparity_scale, turbo};
pub use error::VizError;
pub use labelled::{Key, Panel, labelled_grid, labelled_row};
pub use sheet::{extrapolation_sheet, photo_set_sheet};
pub use weight_map::{weight_map_image, weight_map_key};
