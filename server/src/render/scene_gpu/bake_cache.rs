//! The billboard atlases of the species: the tiles to bake, and the disk cache of the baked
//! atlases (PNG entries keyed by the species' content).

use super::GpuMesh;
use crate::prep::cache::{DiskCache, KeyBuilder};
use crate::prep::hlp;
use crate::prep::lod::{BILLBOARD_VIEWS, Billboard};
use crate::render::RenderError;
use crate::render::bake::{BakeDraw, BakeTile};
use crate::scene::plant::PlantModel;
use std::ops::Range;

/// Pixel size of one billboard atlas tile.
pub(super) const BILLBOARD_TILE: u32 = 64;
/// Atlas tiles per billboard: one per view of [`BILLBOARD_VIEWS`].
pub(super) const VIEWS: usize = BILLBOARD_VIEWS.len();

/// The atlas tiles of a species: the views of each HLP billboard in `boards`, showing the
/// foliage of that HLP (the `hlp_ranges` of the `full` meshes), then the views of the whole
/// plant's billboard `plant_board`, showing every full mesh.
pub(super) fn bake_tiles<'a>(
    full: &'a [GpuMesh],
    hlp_ranges: &[Option<Vec<Range<u32>>>],
    boards: &[Billboard],
    plant_board: Billboard,
) -> Vec<BakeTile<'a>> {
    let mut tiles = Vec::with_capacity(VIEWS * (boards.len() + 1));
    for (h, board) in boards.iter().enumerate() {
        for view in 0..VIEWS {
            let draws = full
                .iter()
                .zip(hlp_ranges)
                .filter_map(|(mesh, ranges)| {
                    let range = ranges.as_ref()?.get(h)?.clone();
                    (!range.is_empty()).then_some(BakeDraw {
                        vertices: &mesh.vertices,
                        indices: &mesh.indices,
                        range,
                        material: &mesh.material,
                    })
                })
                .collect();
            tiles.push(BakeTile { matrix: board.bake_matrix(view), draws });
        }
    }
    for view in 0..VIEWS {
        let draws = full
            .iter()
            .map(|mesh| BakeDraw {
                vertices: &mesh.vertices,
                indices: &mesh.indices,
                range: 0..mesh.index_count,
                material: &mesh.material,
            })
            .collect();
        tiles.push(BakeTile { matrix: plant_board.bake_matrix(view), draws });
    }
    tiles
}

/// The billboard atlas (`size` pixels) of `model` with HLPs of `hlp_radius`: from `disk` when
/// it holds one, else made by `bake` (and stored in `disk`).
pub(super) fn cached_billboards(
    disk: Option<&DiskCache>,
    model: &PlantModel,
    hlp_radius: f32,
    size: (u32, u32),
    bake: impl FnOnce() -> Result<image::RgbaImage, RenderError>,
) -> Result<image::RgbaImage, RenderError> {
    let Some(disk) = disk else {
        return bake();
    };
    let mut failure = None;
    let image = disk.get_or_compute(
        "billboards",
        &bake_key(model, hlp_radius),
        |bytes| decode_png(bytes, size),
        encode_png,
        || {
            bake().unwrap_or_else(|e| {
                failure = Some(e);
                image::RgbaImage::new(1, 1)
            })
        },
    );
    match failure {
        Some(error) => Err(error),
        None => Ok(image),
    }
}

/// A content key for a species' baked billboards: geometry, textures, HLPs and bake settings.
fn bake_key(model: &PlantModel, hlp_radius: f32) -> String {
    // v2: foliage is baked with the leaf shape maps of its textures.
    let mut key = KeyBuilder::default().bytes(b"billboards v2").u64(hlp::model_hash(model)).f32(hlp_radius);
    key = key.u64(u64::from(BILLBOARD_TILE));
    for part in &model.parts {
        let m = &part.material;
        key = m.base_color.iter().fold(key, |k, c| k.f32(*c)).f32(m.alpha_cutoff.unwrap_or(-1.0));
        for uv in &part.mesh.uvs {
            key = key.f32(uv[0]).f32(uv[1]);
        }
        if let Some(texture) = &m.texture {
            key = key.u64(u64::from(texture.width())).bytes(texture.as_raw());
        }
    }
    key.finish()
}

fn encode_png(image: &image::RgbaImage) -> Vec<u8> {
    let mut bytes = Vec::new();
    // Encoding an in-memory RGBA image to PNG cannot fail; an empty entry is recomputed.
    let _ = image.write_to(&mut std::io::Cursor::new(&mut bytes), image::ImageFormat::Png);
    bytes
}

fn decode_png(bytes: &[u8], size: (u32, u32)) -> Option<image::RgbaImage> {
    let image = image::load_from_memory_with_format(bytes, image::ImageFormat::Png).ok()?.to_rgba8();
    (image.dimensions() == size).then_some(image)
}
