//! Operations on views and disparity maps (conventions §2): filling invalid
//! disparities from the background side, the median filter of a float map,
//! backward warping of a view by a disparity, image-quality measures
//! (PSNR, SSIM), and crops of views as planar float buffers. File formats and writing are `mbs-core`'s.

pub mod fill;
pub mod median;
pub mod planar;
pub mod quality;
pub mod resample;
