//! Loading plant models from glTF 2.0 files (.glb, or .gltf with external or base64 buffers).
//!
//! The loader reads buffers and images itself (rather than through `gltf::import`) so that a
//! missing file is reported by name and no malformed input can make it panic.

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use glam::{Mat3, Mat4, Vec3, Vec4};
use gltf::accessor::{DataType, Dimensions};
use gltf::material::AlphaMode;
use gltf::mesh::Mode;
use gltf::{Accessor, Document, Semantic};
use image::RgbaImage;

use crate::scene::mesh::Mesh;
use crate::scene::plant::{
    Material, MeshPart, ModelError, PartKind, PlantModel, append_mesh, smooth_normals, unit_or_up,
};

/// glTF's y-up frame to the scene's z-up frame: (x, y, z) → (x, −z, y).
const Y_UP_TO_Z_UP: Mat4 = Mat4::from_cols(Vec4::X, Vec4::Z, Vec4::NEG_Y, Vec4::W);

/// Loads .glb / .gltf (external or base64 buffers, textures) and converts glTF's y-up to z-up
/// ((x,y,z) → (x,-z,y)), applies node transforms (whole scene graph of the default scene),
/// re-bases so min z = 0.
///
/// Primitives sharing a material are merged into one [`MeshPart`], classified by
/// [`classify_material`]. Missing normals are computed (smooth), missing UVs become zeros,
/// points and lines are skipped, triangle strips and fans are unrolled.
pub fn load_gltf(path: &Path) -> Result<PlantModel, ModelError> {
    let bytes = std::fs::read(path).map_err(|error| ModelError::Read { path: path.to_path_buf(), error })?;
    if !looks_like_gltf(&bytes) {
        return Err(ModelError::NotGltf { path: path.to_path_buf() });
    }
    // The gltf crate takes the GLB header's 12 bytes off the length the header declares
    // without checking that it is at least that.
    if let Some(declared) = bytes.get(8..12).filter(|_| bytes.starts_with(b"glTF"))
        && let Ok(declared) = <[u8; 4]>::try_from(declared).map(u32::from_le_bytes)
        && declared < 12
    {
        let error = gltf::binary::Error::Length { length: declared, length_read: bytes.len() };
        return Err(ModelError::Gltf { path: path.to_path_buf(), error: gltf::Error::Binary(error) });
    }
    let gltf_error = |error| ModelError::Gltf { path: path.to_path_buf(), error };
    let gltf::Gltf { document, blob } = gltf::Gltf::from_slice_without_validation(&bytes).map_err(gltf_error)?;
    // The crate's validation reads each primitive's POSITION accessor before it checks that
    // the index names one.
    let json = document.into_json();
    for (mesh, m) in json.meshes.iter().enumerate() {
        for (primitive, p) in m.primitives.iter().enumerate() {
            let position = p.attributes.get(&gltf::json::validation::Checked::Valid(Semantic::Positions));
            if let Some(index) = position.map(|i| i.value()).filter(|&i| i >= json.accessors.len()) {
                let reason = format!("accessor {index} does not exist (there are {})", json.accessors.len());
                return Err(ModelError::BadAccessor {
                    path: path.to_path_buf(),
                    mesh,
                    primitive,
                    attribute: "POSITION",
                    reason,
                });
            }
        }
    }
    let document = Document::from_json(json).map_err(gltf_error)?;
    let base = path.parent().unwrap_or(Path::new(""));
    let buffers = load_buffers(path, base, &document, blob)?;
    let mut loader = Loader { path, base, document: &document, buffers, images: HashMap::new(), parts: Vec::new() };
    if let Some(scene) = document.default_scene().or_else(|| document.scenes().next()) {
        for node in scene.nodes() {
            loader.visit(node, Y_UP_TO_Z_UP, &mut Vec::new())?;
        }
    }
    if loader.parts.is_empty() {
        return Err(ModelError::NoGeometry { path: path.to_path_buf() });
    }
    let mut model = PlantModel {
        name: path.file_stem().map(|stem| stem.to_string_lossy().into_owned()).unwrap_or_default(),
        parts: loader.parts.into_iter().map(|(_, part)| part).collect(),
    };
    model.rest_on_ground();
    Ok(model)
}

/// The leaf/wood rule: a primitive is [`PartKind::Foliage`] if its material's alphaMode is
/// MASK or BLEND, or its material name (case-insensitive) contains "leaf", "leaves", "foliage",
/// "needle" or "frond"; otherwise it is [`PartKind::Wood`].
pub fn classify_material(alpha_mode: AlphaMode, name: Option<&str>) -> PartKind {
    const FOLIAGE_WORDS: [&str; 5] = ["leaf", "leaves", "foliage", "needle", "frond"];
    let name = name.unwrap_or_default().to_lowercase();
    if alpha_mode != AlphaMode::Opaque || FOLIAGE_WORDS.iter().any(|word| name.contains(word)) {
        PartKind::Foliage
    } else {
        PartKind::Wood
    }
}

/// State of one load: the document, its buffers, decoded images and the parts built so far.
struct Loader<'a> {
    path: &'a Path,
    base: &'a Path,
    document: &'a Document,
    buffers: Vec<Vec<u8>>,
    /// Decoded images by glTF image index, shared between materials.
    images: HashMap<usize, Arc<RgbaImage>>,
    /// Parts keyed by glTF material index (`None`: the default material).
    parts: Vec<(Option<usize>, MeshPart)>,
}

impl Loader<'_> {
    /// Adds the meshes of `node` and its descendants; `parent` maps the node's parent frame to
    /// scene space. `ancestors` guards against cyclic (invalid) node graphs.
    fn visit(&mut self, node: gltf::Node, parent: Mat4, ancestors: &mut Vec<usize>) -> Result<(), ModelError> {
        let transform = parent * Mat4::from_cols_array_2d(&node.transform().matrix());
        if let Some(mesh) = node.mesh() {
            for primitive in mesh.primitives() {
                self.add_primitive(mesh.index(), &primitive, transform)?;
            }
        }
        ancestors.push(node.index());
        for child in node.children() {
            if !ancestors.contains(&child.index()) {
                self.visit(child, transform, ancestors)?;
            }
        }
        ancestors.pop();
        Ok(())
    }

    /// Reads one primitive, transforms it to scene space and merges it into its material's part.
    fn add_primitive(&mut self, mesh: usize, primitive: &gltf::Primitive, transform: Mat4) -> Result<(), ModelError> {
        let material = primitive.material();
        let uv_set = material.pbr_metallic_roughness().base_color_texture().map_or(0, |info| info.tex_coord());
        let Some(mut local) = self.read_primitive(mesh, primitive, uv_set)? else {
            return Ok(());
        };

        let normal_matrix = Mat3::from_mat4(transform).inverse().transpose();
        for position in &mut local.positions {
            *position = transform.transform_point3(Vec3::from(*position)).to_array();
        }
        for normal in &mut local.normals {
            *normal = unit_or_up(normal_matrix * Vec3::from(*normal));
        }
        if transform.determinant() < 0.0 {
            // A mirroring transform turns counter-clockwise triangles clockwise.
            for triangle in local.indices.chunks_exact_mut(3) {
                triangle.swap(1, 2);
            }
        }

        let key = material.index();
        if let Some((_, part)) = self.parts.iter_mut().find(|(k, _)| *k == key) {
            append_mesh(&mut part.mesh, &local);
        } else {
            let part = MeshPart {
                kind: classify_material(material.alpha_mode(), material.name()),
                mesh: local,
                material: self.material(&material)?,
            };
            self.parts.push((key, part));
        }
        Ok(())
    }

    /// Reads positions, normals, UVs (set `uv_set`) and triangle indices of a primitive in its
    /// local frame; `None` when it has no whole triangle (points, lines, too few indices).
    fn read_primitive(
        &self,
        mesh: usize,
        primitive: &gltf::Primitive,
        uv_set: u32,
    ) -> Result<Option<Mesh>, ModelError> {
        let bad_accessor = |attribute, reason| ModelError::BadAccessor {
            path: self.path.to_path_buf(),
            mesh,
            primitive: primitive.index(),
            attribute,
            reason,
        };
        let checks: [(&str, Option<Accessor>, Dimensions, &[DataType]); 4] = [
            ("POSITION", primitive.get(&Semantic::Positions), Dimensions::Vec3, &[DataType::F32]),
            ("NORMAL", primitive.get(&Semantic::Normals), Dimensions::Vec3, &[DataType::F32]),
            (
                "TEXCOORD",
                primitive.get(&Semantic::TexCoords(uv_set)),
                Dimensions::Vec2,
                &[DataType::F32, DataType::U8, DataType::U16],
            ),
            ("index", primitive.indices(), Dimensions::Scalar, &[DataType::U8, DataType::U16, DataType::U32]),
        ];
        for (attribute, accessor, dimensions, types) in checks {
            if let Some(reason) = accessor.and_then(|a| self.accessor_problem(&a, dimensions, types)) {
                return Err(bad_accessor(attribute, reason));
            }
        }

        let reader = primitive.reader(|buffer: gltf::Buffer| self.buffers.get(buffer.index()).map(Vec::as_slice));
        let positions: Vec<[f32; 3]> = reader
            .read_positions()
            .ok_or_else(|| ModelError::NoPositions {
                path: self.path.to_path_buf(),
                mesh,
                primitive: primitive.index(),
            })?
            .collect();
        let vertex_count = positions.len();
        let raw_indices: Vec<u32> = match reader.read_indices() {
            Some(indices) => indices.into_u32().collect(),
            None if primitive.indices().is_some() => {
                return Err(bad_accessor("index", "data not readable".into()));
            }
            None => (0..vertex_count as u32).collect(),
        };
        let Some(indices) = triangle_list(primitive.mode(), &raw_indices) else {
            return Ok(None);
        };
        if indices.is_empty() {
            return Ok(None);
        }
        if let Some(&index) = indices.iter().find(|&&i| i as usize >= vertex_count) {
            return Err(ModelError::IndexOutOfRange {
                path: self.path.to_path_buf(),
                mesh,
                primitive: primitive.index(),
                index,
                vertex_count,
            });
        }
        let normals = reader
            .read_normals()
            .map(Iterator::collect::<Vec<_>>)
            .filter(|normals| normals.len() == vertex_count)
            .unwrap_or_else(|| smooth_normals(&positions, &indices));
        let uvs = reader
            .read_tex_coords(uv_set)
            .map(|uvs| uvs.into_f32().collect::<Vec<_>>())
            .filter(|uvs| uvs.len() == vertex_count)
            .unwrap_or_else(|| vec![[0.0; 2]; vertex_count]);
        Ok(Some(Mesh { positions, normals, uvs, indices }))
    }

    /// Why `accessor` cannot be read safely as `dimensions` of one of `types` (the `gltf`
    /// readers assert on these), or `None` when it can.
    fn accessor_problem(&self, accessor: &Accessor, dimensions: Dimensions, types: &[DataType]) -> Option<String> {
        if accessor.dimensions() != dimensions || !types.contains(&accessor.data_type()) {
            return Some(format!(
                "{:?} of {:?}, expected {dimensions:?} of one of {types:?}",
                accessor.dimensions(),
                accessor.data_type()
            ));
        }
        if accessor.sparse().is_some() {
            return Some("sparse accessors are not supported".into());
        }
        let Some(view) = accessor.view() else {
            return Some("no buffer view".into());
        };
        let size = accessor.size();
        let stride = view.stride().unwrap_or(size);
        let accessor_end = accessor
            .count()
            .checked_sub(1)
            .and_then(|last| last.checked_mul(stride))
            .and_then(|bytes| bytes.checked_add(size))
            .and_then(|bytes| bytes.checked_add(accessor.offset()));
        let view_end = view.offset().checked_add(view.length());
        let buffer_len = self.buffers.get(view.buffer().index()).map(Vec::len);
        if stride < size {
            Some(format!("byte stride {stride} below element size {size}"))
        } else if accessor_end.is_none_or(|end| end > view.length()) {
            Some("elements extend past the buffer view (or count is 0)".into())
        } else if view_end.zip(buffer_len).is_none_or(|(end, len)| end > len) {
            Some("buffer view extends past its buffer".into())
        } else {
            None
        }
    }

    /// The [`Material`] of a glTF material, loading its base colour texture.
    fn material(&mut self, material: &gltf::Material) -> Result<Material, ModelError> {
        let pbr = material.pbr_metallic_roughness();
        let texture = match pbr.base_color_texture() {
            Some(info) => Some(self.image(info.texture().source().index())?),
            None => None,
        };
        let name = match (material.name(), material.index()) {
            (Some(name), _) => name.to_owned(),
            (None, Some(index)) => format!("material {index}"),
            (None, None) => "default".to_owned(),
        };
        // BLEND is approximated by alpha testing: the G-buffer pass has no blending.
        let alpha_cutoff = match material.alpha_mode() {
            AlphaMode::Opaque => None,
            AlphaMode::Mask => Some(material.alpha_cutoff().unwrap_or(0.5)),
            AlphaMode::Blend => Some(0.5),
        };
        Ok(Material {
            name,
            base_color: pbr.base_color_factor(),
            texture,
            alpha_cutoff,
            double_sided: material.double_sided(),
        })
    }

    /// Decodes glTF image `index` to 8-bit RGBA (any PNG/JPEG pixel format, 16-bit included),
    /// once per load.
    fn image(&mut self, index: usize) -> Result<Arc<RgbaImage>, ModelError> {
        if let Some(image) = self.images.get(&index) {
            return Ok(Arc::clone(image));
        }
        let error = |reason: String| ModelError::Image { path: self.path.to_path_buf(), index, reason };
        let json = self.document.as_json().images.get(index).ok_or_else(|| error("no such image".into()))?;
        let encoded = if let Some(view) = json.buffer_view {
            self.document
                .views()
                .nth(view.value())
                .and_then(|view| {
                    let start = view.offset();
                    let bytes = self.buffers.get(view.buffer().index())?;
                    bytes.get(start..start.checked_add(view.length())?)
                })
                .ok_or_else(|| error("buffer view out of range".into()))?
                .to_vec()
        } else if let Some(uri) = &json.uri {
            read_uri(self.base, uri).map_err(|e| error(format!("uri {uri}: {e}")))?
        } else {
            return Err(error("neither uri nor bufferView".into()));
        };
        let image = image::load_from_memory(&encoded).map_err(|e| error(e.to_string()))?.into_rgba8();
        let image = Arc::new(image);
        self.images.insert(index, Arc::clone(&image));
        Ok(image)
    }
}

/// Reads the data of every buffer: the GLB `BIN` chunk, a base64 `data:` URI or a file.
fn load_buffers(
    path: &Path,
    base: &Path,
    document: &Document,
    mut blob: Option<Vec<u8>>,
) -> Result<Vec<Vec<u8>>, ModelError> {
    document
        .buffers()
        .map(|buffer| {
            let index = buffer.index();
            let invalid = |reason: String| ModelError::InvalidBuffer { path: path.to_path_buf(), index, reason };
            let data = match buffer.source() {
                gltf::buffer::Source::Bin => {
                    blob.take().ok_or_else(|| invalid("the file has no binary (BIN) chunk".into()))?
                }
                gltf::buffer::Source::Uri(uri) => read_uri(base, uri).map_err(|e| match e {
                    UriError::Missing { error, .. } => {
                        ModelError::MissingBuffer { path: path.to_path_buf(), index, uri: uri.to_owned(), error }
                    }
                    UriError::Invalid(reason) => invalid(format!("uri {uri}: {reason}")),
                })?,
            };
            if data.len() < buffer.length() {
                return Err(invalid(format!("{} bytes, expected {}", data.len(), buffer.length())));
            }
            Ok(data)
        })
        .collect()
}

/// Why the data behind a URI cannot be read.
#[derive(Debug, thiserror::Error)]
enum UriError {
    /// The file it names cannot be read.
    #[error("cannot read {path}: {error}")]
    Missing { path: PathBuf, error: std::io::Error },
    /// The URI itself is unusable.
    #[error("{0}")]
    Invalid(String),
}

/// Reads the bytes a glTF URI points at: a base64 `data:` URI, a `file:` URI or a
/// (percent-encoded) path relative to `base`.
fn read_uri(base: &Path, uri: &str) -> Result<Vec<u8>, UriError> {
    if uri.starts_with("data:") {
        // Decoding data URIs needs no base directory; the gltf crate does it without panicking.
        return gltf::buffer::Data::from_source(gltf::buffer::Source::Uri(uri), None)
            .map(|data| data.0)
            .map_err(|e| UriError::Invalid(e.to_string()));
    }
    let file = match uri.strip_prefix("file://").or_else(|| uri.strip_prefix("file:")) {
        Some(absolute) => absolute,
        None if uri.contains(':') => {
            return Err(UriError::Invalid("unsupported URI scheme".into()));
        }
        None => uri,
    };
    let decoded = percent_decode(file).ok_or_else(|| UriError::Invalid("malformed percent-encoding".into()))?;
    let path = base.join(decoded);
    std::fs::read(&path).map_err(|error| UriError::Missing { path, error })
}

/// Decodes `%XX` escapes; `None` when an escape is malformed or the result is not UTF-8.
fn percent_decode(text: &str) -> Option<String> {
    let bytes = text.as_bytes();
    let mut decoded = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        if bytes[i] == b'%' {
            let hex = bytes.get(i + 1..i + 3)?;
            if !hex.iter().all(u8::is_ascii_hexdigit) {
                return None;
            }
            decoded.push(u8::from_str_radix(std::str::from_utf8(hex).ok()?, 16).ok()?);
            i += 3;
        } else {
            decoded.push(bytes[i]);
            i += 1;
        }
    }
    String::from_utf8(decoded).ok()
}

/// Whether `bytes` start like binary glTF (`glTF` magic) or a JSON object.
fn looks_like_gltf(bytes: &[u8]) -> bool {
    let text = bytes.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(bytes);
    bytes.starts_with(b"glTF") || text.trim_ascii_start().starts_with(b"{")
}

/// Converts a primitive's index list to a triangle list: triangles as they are, strips and fans
/// unrolled with glTF's winding (their degenerate triangles dropped); `None` for points and lines.
fn triangle_list(mode: Mode, indices: &[u32]) -> Option<Vec<u32>> {
    let not_degenerate = |t: &[u32; 3]| t[0] != t[1] && t[1] != t[2] && t[0] != t[2];
    let triangles: Vec<[u32; 3]> = match mode {
        Mode::Triangles => return Some(indices[..indices.len() / 3 * 3].to_vec()),
        Mode::TriangleStrip => indices
            .windows(3)
            .enumerate()
            .map(|(i, w)| if i % 2 == 0 { [w[0], w[1], w[2]] } else { [w[0], w[2], w[1]] })
            .filter(not_degenerate)
            .collect(),
        Mode::TriangleFan => match indices.split_first() {
            Some((&first, rest)) => rest.windows(2).map(|w| [first, w[0], w[1]]).filter(not_degenerate).collect(),
            None => Vec::new(),
        },
        Mode::Points | Mode::Lines | Mode::LineLoop | Mode::LineStrip => return None,
    };
    Some(triangles.into_iter().flatten().collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn foliage_by_alpha_mode_or_name() {
        assert_eq!(classify_material(AlphaMode::Mask, Some("Bark")), PartKind::Foliage);
        assert_eq!(classify_material(AlphaMode::Blend, None), PartKind::Foliage);
        for name in ["PineTree_Leaves", "OakLEAF", "foliage_2", "Needles", "PalmFrond"] {
            assert_eq!(classify_material(AlphaMode::Opaque, Some(name)), PartKind::Foliage);
        }
        assert_eq!(classify_material(AlphaMode::Opaque, Some("NormalTree_Bark")), PartKind::Wood);
        assert_eq!(classify_material(AlphaMode::Opaque, None), PartKind::Wood);
    }

    #[test]
    fn y_up_becomes_z_up() {
        let p = Y_UP_TO_Z_UP.transform_point3(Vec3::new(1.0, 2.0, 3.0));
        assert_eq!(p, Vec3::new(1.0, -3.0, 2.0));
        assert!(Y_UP_TO_Z_UP.determinant() > 0.0);
    }

    #[test]
    fn strips_and_fans_unroll_with_gltf_winding() {
        assert_eq!(triangle_list(Mode::TriangleStrip, &[0, 1, 2, 3, 3, 4]), Some(vec![0, 1, 2, 1, 3, 2]));
        assert_eq!(triangle_list(Mode::TriangleFan, &[0, 1, 2, 3]), Some(vec![0, 1, 2, 0, 2, 3]));
        assert_eq!(triangle_list(Mode::TriangleFan, &[]), Some(vec![]));
        assert_eq!(triangle_list(Mode::Triangles, &[0, 1, 2, 3]), Some(vec![0, 1, 2]));
        assert_eq!(triangle_list(Mode::Lines, &[0, 1]), None);
        assert_eq!(triangle_list(Mode::Points, &[0]), None);
    }

    #[test]
    fn percent_decoding() {
        assert_eq!(percent_decode("a%20b.bin").as_deref(), Some("a b.bin"));
        assert_eq!(percent_decode("plain.bin").as_deref(), Some("plain.bin"));
        assert_eq!(percent_decode("bad%2"), None);
        assert_eq!(percent_decode("bad%+1x"), None);
        assert_eq!(percent_decode("%FF"), None);
    }

    #[test]
    fn gltf_sniffing() {
        assert!(looks_like_gltf(b"glTF\x02\0\0\0"));
        assert!(looks_like_gltf(b"  \n{\"asset\":{}}"));
        assert!(looks_like_gltf(b"\xEF\xBB\xBF{}"));
        assert!(!looks_like_gltf(b"\x89PNG\r\n"));
        assert!(!looks_like_gltf(b""));
    }

    #[test]
    fn uris_resolve_relative_to_base_and_reject_other_schemes() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("my buffer.bin"), [1, 2, 3]).unwrap();
        assert_eq!(read_uri(dir.path(), "my%20buffer.bin").unwrap(), vec![1, 2, 3]);
        assert!(matches!(read_uri(dir.path(), "gone.bin"), Err(UriError::Missing { .. })));
        assert!(matches!(read_uri(dir.path(), "https://x/y.bin"), Err(UriError::Invalid(_))));
        let decoded = read_uri(dir.path(), "data:application/octet-stream;base64,AQID").unwrap();
        assert_eq!(&decoded[..3], &[1, 2, 3]);
    }

    /// Inputs the fuzzer found that made the gltf crate panic (`fuzz/regressions/gltf_model/`)
    /// are errors naming what is wrong.
    #[test]
    fn a_short_glb_length_and_a_missing_position_accessor_are_errors() {
        let dir = tempfile::tempdir().unwrap();
        let glb = dir.path().join("short.glb");
        std::fs::write(&glb, b"glTF\x02\0\0\0\x04\0\0\0").unwrap();
        assert!(matches!(load_gltf(&glb), Err(ModelError::Gltf { .. })));
        let json = dir.path().join("no-accessor.gltf");
        let text = r#"{"asset":{"version":"2.0"},"meshes":[{"primitives":[{"attributes":{"POSITION":0}}]}]}"#;
        std::fs::write(&json, text).unwrap();
        let error = load_gltf(&json).expect_err("no accessor 0");
        assert!(matches!(error, ModelError::BadAccessor { attribute: "POSITION", .. }), "{error}");
        assert!(error.to_string().contains("accessor 0 does not exist"), "{error}");
    }
}
