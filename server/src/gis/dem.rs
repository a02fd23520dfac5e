//! DEMs at the size a terrain needs: a window of the file (a scene's crop extent), read from a
//! GeoTIFF's strips, tiles and overviews without decoding the rest, then averaged down to a
//! cell budget. A national agency's lidar tile or a COG of a county loads in bounded memory.

use std::path::Path;

use super::error::GisError;
use super::geotiff::read_geotiff_window;
use super::raster::{self, Extent, Raster, load_raster};

/// Loads the cells of the DEM at `path` that meet `window` (in the file's CRS; the whole DEM
/// without one) with at most `max_cells` cells: a GeoTIFF through
/// [`read_geotiff_window`] (only the chunks of the window, from the coarsest fitting
/// overview), other formats whole and cropped; what is still larger is averaged down by the
/// smallest whole factor that fits ([`Raster::decimate`]).
pub fn load_dem(path: &Path, window: Option<&Extent>, max_cells: u64) -> Result<Raster, GisError> {
    let ext = path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase);
    let dem = match ext.as_deref() {
        Some("tif" | "tiff") => read_geotiff_window(path, window, max_cells)?,
        _ => {
            let dem = load_raster(path)?;
            match window {
                None => dem,
                Some(w) => {
                    let (col, row, width, height) = dem.window_of(w).ok_or_else(|| GisError::WindowOutside {
                        path: path.to_path_buf(),
                        window: *w,
                        extent: dem.extent(),
                        crs: dem.crs,
                    })?;
                    dem.crop(col, row, width, height)?
                }
            }
        }
    };
    let factor = raster::fit_factor(dem.width, dem.height, max_cells);
    Ok(if factor > 1 { dem.decimate(factor) } else { dem })
}
