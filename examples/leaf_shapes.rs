//! Writes `docs/leaf_shapes.png`, the leaf shape maps (thesis 4.1, `prep::leaf_shape`) of the
//! sample scene's leaf textures, like thesis Fig. 4.5–4.6. One row per texture (Quaternius
//! `NormalTree` leaves, `PineTree` needles, the procedural broadleaf leaf); columns: the
//! original alpha, the shape map's alpha, then the shapes at four alpha thresholds from α_max
//! (the original leaf) to α_min (the most abstract shape), drawn in the texture's colour on
//! white with their outline (eq. 4.1, Δα = one shape step) in ink. Usage:
//!
//! ```text
//! cargo run --example leaf_shapes [-- OUT.png]   # OUT defaults to docs/leaf_shapes.png
//! ```

use image::{Rgba, RgbaImage, imageops};
use landsketch::prep::leaf_shape::{ShapeParams, on_outline, shape_map};
use landsketch::scene::gltf_loader::load_gltf;
use landsketch::scene::plant::{PartKind, PlantModel};
use landsketch::scene::procedural::{ProceduralKind, procedural_plant};
use std::path::Path;

/// Side of one tile in pixels.
const TILE: u32 = 256;
/// Gap between tiles.
const GAP: u32 = 8;

/// The first foliage texture of `model` and its alpha cutoff.
fn leaf_texture(model: &PlantModel) -> anyhow::Result<(RgbaImage, f32)> {
    let part = model.parts_of(PartKind::Foliage).next().ok_or_else(|| anyhow::anyhow!("{}: no foliage", model.name))?;
    let texture = part.material.texture.as_ref().ok_or_else(|| anyhow::anyhow!("{}: no leaf texture", model.name))?;
    let square = imageops::resize(texture.as_ref(), TILE, TILE, imageops::FilterType::Nearest);
    Ok((square, part.material.alpha_cutoff.unwrap_or(0.5)))
}

/// The alpha channel as grey.
fn alpha_tile(image: &RgbaImage) -> RgbaImage {
    RgbaImage::from_fn(image.width(), image.height(), |x, y| {
        let a = image.get_pixel(x, y)[3];
        Rgba([a, a, a, 255])
    })
}

/// The shape at `alpha_t`: texture colour where α ≥ α_t, white elsewhere, ink on the outline.
fn shape_tile(map: &RgbaImage, alpha_t: f32, delta: f32) -> RgbaImage {
    RgbaImage::from_fn(map.width(), map.height(), |x, y| {
        let p = map.get_pixel(x, y);
        let a = f32::from(p[3]) / 255.0;
        if on_outline(a, alpha_t, delta) {
            Rgba([20, 20, 26, 255])
        } else if a >= alpha_t {
            Rgba([p[0], p[1], p[2], 255])
        } else {
            Rgba([255, 255, 255, 255])
        }
    })
}

fn main() -> anyhow::Result<()> {
    let out = std::env::args().nth(1).unwrap_or_else(|| "docs/src/images/leaf_shapes.png".into());
    let models = [
        load_gltf(Path::new("data/models/quaternius/NormalTree_1_textured.gltf"))?,
        load_gltf(Path::new("data/models/quaternius/PineTree_1_textured.gltf"))?,
        procedural_plant(ProceduralKind::Broadleaf, 3),
    ];
    // Shapes shown: i of α_i from the original (0) to the most abstract (n).
    let n = ShapeParams::default().iterations;
    let shown = [0, n / 3, 2 * n / 3, n];
    let columns = 2 + shown.len() as u32;
    let mut sheet = RgbaImage::from_pixel(
        columns * TILE + (columns + 1) * GAP,
        models.len() as u32 * TILE + (models.len() as u32 + 1) * GAP,
        Rgba([200, 200, 200, 255]),
    );
    for (row, model) in models.iter().enumerate() {
        let (texture, cutoff) = leaf_texture(model)?;
        let params = ShapeParams { alpha_max: cutoff, ..ShapeParams::default() };
        let map = shape_map(&texture, &params);
        let delta = params.level(0) - params.level(1);
        let mut tiles = vec![alpha_tile(&texture), alpha_tile(&map)];
        tiles.extend(shown.iter().map(|&i| shape_tile(&map, params.level(i), delta)));
        for (column, tile) in tiles.iter().enumerate() {
            let x = GAP + column as u32 * (TILE + GAP);
            let y = GAP + row as u32 * (TILE + GAP);
            imageops::replace(&mut sheet, tile, i64::from(x), i64::from(y));
        }
        let levels: Vec<String> = shown.iter().map(|&i| format!("{:.3}", params.level(i))).collect();
        println!("{}: α_max {cutoff}, shapes at α_t = {}", model.name, levels.join(", "));
    }
    sheet.save(&out)?;
    println!("{out}");
    Ok(())
}
