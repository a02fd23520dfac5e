//! Hand-made little-endian TIFFs for tests of what the `tiff` encoder cannot write:
//! decompression bombs (strips that all point to one stream) and JPEG-compressed GeoTIFFs.

/// TIFF field types used here.
pub const SHORT: u16 = 3;
/// 32-bit unsigned.
pub const LONG: u16 = 4;
/// 64-bit float.
pub const DOUBLE: u16 = 12;

/// One IFD entry: tag, field type, count and the value's little-endian bytes.
pub type Entry = (u16, u16, u32, Vec<u8>);

/// Little-endian bytes of SHORT values.
pub fn shorts(v: &[u16]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_le_bytes()).collect()
}

/// Little-endian bytes of LONG values.
pub fn longs(v: &[u32]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_le_bytes()).collect()
}

/// Little-endian bytes of DOUBLE values.
pub fn doubles(v: &[f64]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_le_bytes()).collect()
}

/// Offset of the data block in a file from [`tiff_file`] (right after the 8-byte header), for
/// the strip or tile offsets of its entries.
pub const DATA_OFFSET: u32 = 8;

/// A TIFF of the header, `data` at [`DATA_OFFSET`] and one IFD of `entries` (sorted here;
/// values over four bytes are stored after the IFD).
pub fn tiff_file(data: &[u8], entries: Vec<Entry>) -> Vec<u8> {
    tiff_images(data, vec![entries])
}

/// [`tiff_file`] with one IFD per image, chained in order (a full-resolution image and its
/// overviews, as a Cloud-Optimized GeoTIFF holds them).
pub fn tiff_images(data: &[u8], images: Vec<Vec<Entry>>) -> Vec<u8> {
    let mut file = b"II*\0".to_vec();
    file.extend_from_slice(&(DATA_OFFSET + data.len() as u32).to_le_bytes());
    file.extend_from_slice(data);
    let count = images.len();
    for (i, mut entries) in images.into_iter().enumerate() {
        entries.sort_by_key(|entry| entry.0);
        let ifd_offset = file.len();
        let arrays_at = ifd_offset + 2 + entries.len() * 12 + 4;
        let mut arrays = Vec::new();
        file.extend_from_slice(&(entries.len() as u16).to_le_bytes());
        for (tag, kind, count, bytes) in &entries {
            file.extend_from_slice(&tag.to_le_bytes());
            file.extend_from_slice(&kind.to_le_bytes());
            file.extend_from_slice(&count.to_le_bytes());
            if bytes.len() <= 4 {
                let mut inline = bytes.clone();
                inline.resize(4, 0);
                file.extend_from_slice(&inline);
            } else {
                file.extend_from_slice(&((arrays_at + arrays.len()) as u32).to_le_bytes());
                arrays.extend_from_slice(bytes);
            }
        }
        let next = if i + 1 < count { arrays_at + arrays.len() } else { 0 };
        file.extend_from_slice(&(next as u32).to_le_bytes());
        file.extend_from_slice(&arrays);
    }
    file
}

/// The GeoTIFF entries placing a `width` × `height` image over the lon/lat rectangle
/// `west`..`east`, `south`..`north` in EPSG:4326.
pub fn geographic_entries(width: u32, height: u32, west: f64, south: f64, east: f64, north: f64) -> Vec<Entry> {
    vec![
        (33550, DOUBLE, 3, doubles(&[(east - west) / f64::from(width), (north - south) / f64::from(height), 0.0])),
        (33922, DOUBLE, 6, doubles(&[0.0, 0.0, 0.0, west, north, 0.0])),
        (34735, SHORT, 8, shorts(&[1, 1, 0, 1, 2048, 0, 1, 4326])),
    ]
}
