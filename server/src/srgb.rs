//! The sRGB transfer function (IEC 61966-2-1) between 8-bit encoded values and linear light,
//! for the colours the scene stores encoded (textures, drapes, class colours) and the ones the
//! renderer averages or shades in linear light.

/// An 8-bit sRGB-encoded value as linear light 0..1.
pub fn to_linear(v: u8) -> f32 {
    let c = f32::from(v) / 255.0;
    if c <= 0.04045 { c / 12.92 } else { ((c + 0.055) / 1.055).powf(2.4) }
}

/// Linear light 0..1 (clamped) as an 8-bit sRGB-encoded value.
pub fn from_linear(linear: f32) -> u8 {
    let c = linear.clamp(0.0, 1.0);
    let s = if c <= 0.003_130_8 { c * 12.92 } else { 1.055 * c.powf(1.0 / 2.4) - 0.055 };
    (s * 255.0).round() as u8
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn encoding_round_trips_every_byte() {
        assert!((0..=255u8).all(|v| from_linear(to_linear(v)) == v));
        assert_eq!((to_linear(0), to_linear(255)), (0.0, 1.0));
    }
}
