//! Image files through the `image` crate: Radiance .hdr, OpenEXR and PNG in; 8-bit sRGB PNG and float32 OpenEXR
//! out. Tone mapping is the caller's (python/lamina/render.py).

use crate::error::{value_error, Result};
use image::{ImageBuffer, Rgb};

/// Reads an image as linear float RGB: (width, height, row-major RGB). PNG and other 8-bit formats are decoded from
/// sRGB by the crate's conversion (values / 255, no linearisation): use .hdr or .exr for radiance.
pub fn read_rgb(path: &str) -> Result<(usize, usize, Vec<f32>)> {
    let img = match image::open(path) {
        Ok(img) => img.into_rgb32f(),
        Err(e) => return value_error(format!("path: cannot read {path:?} as an image: {e}")),
    };
    Ok((img.width() as usize, img.height() as usize, img.into_raw()))
}

/// Writes 8-bit RGB (row-major, already tone mapped and encoded) as a PNG.
pub fn write_png(path: &str, width: usize, height: usize, rgb: Vec<u8>) -> Result<()> {
    let Some(img) = ImageBuffer::<Rgb<u8>, _>::from_raw(width as u32, height as u32, rgb) else {
        return value_error("image: RGB data does not match its width and height");
    };
    img.save_with_format(path, image::ImageFormat::Png)
        .or_else(|e| value_error(format!("path: cannot write {path:?}: {e}")))
}

/// Writes linear float RGB (row-major) as an OpenEXR file.
pub fn write_exr(path: &str, width: usize, height: usize, rgb: Vec<f32>) -> Result<()> {
    let Some(img) = ImageBuffer::<Rgb<f32>, _>::from_raw(width as u32, height as u32, rgb) else {
        return value_error("image: RGB data does not match its width and height");
    };
    img.save_with_format(path, image::ImageFormat::OpenExr)
        .or_else(|e| value_error(format!("path: cannot write {path:?}: {e}")))
}
