//! Writes the default art maps as PNGs (see `data/artmaps/README.md`): one tonal art map strip
//! per stroke style (6 tone levels of 256 × 256, lightest first) and four silhouette art maps
//! of 256 × 32. Usage:
//!
//! ```text
//! cargo run --example make_artmaps [-- OUT_DIR]   # OUT_DIR defaults to data/artmaps
//! ```

use landsketch::render::artmaps::{TamStyle, generate_sams, generate_tam};
use std::path::PathBuf;

/// Side of mip 0 of each tone image.
const TAM_SIZE: u32 = 256;
/// Tone levels per TAM.
const TAM_LEVELS: usize = 6;
/// SAM size: length along the contour × support width.
const SAM_SIZE: (u32, u32) = (256, 32);
/// Seed of every default art map.
const SEED: u64 = 1;

fn main() -> anyhow::Result<()> {
    let out = PathBuf::from(std::env::args().nth(1).unwrap_or_else(|| "data/artmaps".into()));
    std::fs::create_dir_all(&out)?;
    for style in TamStyle::ALL {
        let name = match style {
            TamStyle::Lines => "lines",
            TamStyle::CrossHatch => "crosshatch",
            TamStyle::Scribble => "scribble",
            TamStyle::Stipple => "stipple",
        };
        let tam = generate_tam(style, TAM_SIZE, TAM_LEVELS, SEED);
        let path = out.join(format!("tam_{name}.png"));
        tam.to_png_strip().save(&path)?;
        let tones: Vec<String> = (0..TAM_LEVELS).map(|l| format!("{:.3}", tam.mean_tone(l, 0))).collect();
        println!("{}: mean tones {}", path.display(), tones.join(" "));
    }
    for (i, sam) in generate_sams(SAM_SIZE.0, SAM_SIZE.1, SEED).iter().enumerate() {
        let path = out.join(format!("sam_{i}.png"));
        sam.image.save(&path)?;
        println!("{}", path.display());
    }
    Ok(())
}
