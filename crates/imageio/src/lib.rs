//! Image files: [`mod@write`] turns linear pixels into files (PNG in sRGB with an exposure,
//! OpenEXR in linear float), always atomically; [`read`] decodes EXR, Radiance HDR, PFM and PNG
//! back into linear RGB, so the metric can compare what the renderer wrote with any reference.
//!
//! Why a crate of its own and not beside the image type ([`base::image`]): the codecs are the one
//! part of the project that needs the `image` crate, and only the application and its studies
//! write or read image files.

#![forbid(unsafe_code)]

pub mod exposure;
pub mod read;
pub mod write;

pub use base::image::*;
pub use read::{
    decode_image, decode_pfm, read_image, read_image_header, read_image_up_to, srgb_decode,
    ImageHeader, MAX_PFM_DIM,
};
pub use write::{
    encode_exr, encode_hdr, encode_pfm, encode_png, srgb_encode, to_srgb8, write_exr, write_png,
    OutputFormat,
};
