//! Terrain: the DEM placed in the scene's local metric frame and triangulated with normals.

use super::SceneError;
use super::cover::Drape;
use super::mesh::Mesh;
use crate::gis::{LocalFrame, Raster, dequantize};

/// The terrain of a scene: its DEM, the frame the DEM is placed in and the triangle mesh.
#[derive(Debug, Clone)]
pub struct Terrain {
    pub dem: Raster,
    pub frame: LocalFrame,
    pub mesh: Mesh,
    /// The colours and land-cover classes laid on the ground (one cell of the albedo without a
    /// land cover or orthophoto); the mesh's uvs address it.
    pub drape: Drape,
}

impl Terrain {
    /// Places `dem` with the ground albedo `albedo` (linear RGB) in its local frame (origin at the DEM's extent centre, see
    /// [`LocalFrame::for_raster`]) and builds one vertex per cell centre, two triangles per
    /// quad of valid cells; quads touching nodata are left out.
    /// A DEM stored in whole units on cells less than ten units wide (a lidar DTM in 8-bit
    /// metres) is first smoothed within half a unit of its values
    /// ([`crate::gis::dequantize`]), so its terraces do not print as speckles of strokes.
    pub fn new(mut dem: Raster, albedo: [f32; 3]) -> Result<Terrain, SceneError> {
        let frame = LocalFrame::for_raster(&dem)?;
        let cell_metres = (dem.transform.cell_width * frame.scale().0).min(dem.transform.cell_height * frame.scale().1);
        if let Some(step) = dequantize::quantization_step(&dem)
            && step > 0.1 * cell_metres
        {
            dequantize::dequantize(&mut dem, step);
            tracing::info!(step, cell_metres, "DEM heights smoothed within half their quantization step");
        }
        let (w, h) = (dem.width, dem.height);
        if w < 2 || h < 2 {
            return Err(SceneError::Invalid(format!(
                "DEM of {w}x{h} cells is too small for a terrain (needs at least 2x2)"
            )));
        }
        let mut positions = Vec::with_capacity(w * h);
        for row in 0..h {
            for col in 0..w {
                let (cx, cy) = dem.cell_center(col, row);
                let (x, y) = frame.to_local(cx, cy);
                let z = dem.get(col, row).unwrap_or(0.0);
                positions.push([x as f32, y as f32, z as f32]);
            }
        }
        let index = |col: usize, row: usize| (row * w + col) as u32;
        let valid = |col: usize, row: usize| dem.get(col, row).is_some();
        let mut indices = Vec::new();
        for row in 0..h - 1 {
            for col in 0..w - 1 {
                if valid(col, row) && valid(col + 1, row) && valid(col, row + 1) && valid(col + 1, row + 1) {
                    // Rows run south: (col, row) is the north-west corner; counter-clockwise from above.
                    let (nw, ne, sw, se) =
                        (index(col, row), index(col + 1, row), index(col, row + 1), index(col + 1, row + 1));
                    indices.extend_from_slice(&[nw, sw, se, nw, se, ne]);
                }
            }
        }
        if indices.is_empty() {
            return Err(SceneError::Invalid("the DEM has no 2x2 block of valid cells to triangulate".into()));
        }
        let normals = (0..h)
            .flat_map(|row| (0..w).map(move |col| (col, row)))
            .map(|(col, row)| {
                // Central differences of height over the neighbours' metric distance.
                let p = |c: usize, r: usize| glam::Vec3::from(positions[r * w + c]);
                let (l, r) = (col.saturating_sub(1), (col + 1).min(w - 1));
                let (n, s) = (row.saturating_sub(1), (row + 1).min(h - 1));
                let dx = p(r, row) - p(l, row);
                let dy = p(col, n) - p(col, s);
                let normal = dx.cross(dy).normalize_or(glam::Vec3::Z);
                normal.to_array()
            })
            .collect();
        let mut terrain = Terrain {
            mesh: Mesh { uvs: vec![[0.0; 2]; positions.len()], positions, normals, indices },
            dem,
            frame,
            drape: Drape::plain(albedo, ([0.0; 2], [1.0; 2])),
        };
        terrain.set_drape(Drape::plain(albedo, terrain.bounds()));
        Ok(terrain)
    }

    /// Lays `drape` on the ground: the mesh's uvs become its texture coordinates.
    pub fn set_drape(&mut self, drape: Drape) {
        for (uv, p) in self.mesh.uvs.iter_mut().zip(&self.mesh.positions) {
            *uv = drape.uv(f64::from(p[0]), f64::from(p[1]));
        }
        self.drape = drape;
    }

    /// Terrain height (metres) at scene position `(x, y)`, bilinear between cell centres;
    /// `None` outside the DEM or next to nodata.
    pub fn height_at(&self, x: f64, y: f64) -> Option<f64> {
        let (cx, cy) = self.frame.to_crs(x, y);
        self.dem.sample_bilinear(cx, cy)
    }

    /// The ground's height at `(x, y)` when an eye at elevation `z` there would be under it
    /// (and see nothing): a camera's z given as a height above the ground instead of an
    /// elevation. `None` where the eye is above the ground or off the terrain.
    pub fn buries(&self, [x, y, z]: [f32; 3]) -> Option<f64> {
        self.height_at(f64::from(x), f64::from(y)).filter(|&ground| f64::from(z) < ground)
    }

    /// The scene-space rectangle `(min, max)` covered by the DEM's cell centres.
    pub fn bounds(&self) -> ([f64; 2], [f64; 2]) {
        let (lo, hi) = self.mesh.bounds().unwrap_or(([0.0; 3], [0.0; 3]));
        ([f64::from(lo[0]), f64::from(lo[1])], [f64::from(hi[0]), f64::from(hi[1])])
    }
}
