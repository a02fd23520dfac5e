//! GPU parameter blocks by name. Every uniform block is a Rust struct with named fields,
//! declared once with [`gpu_block!`]: `encase` lays it out by WGSL's uniform rules and the
//! macro derives the WGSL `struct` the shaders read, so `post.contour_strength` in a shader is
//! [`super::style::PostStyle::contour_strength`] here and no layout is written twice.

use encase::ShaderType;
use encase::internal::WriteInto;

/// A type with a WGSL spelling, for the declarations derived from [`gpu_block!`].
pub trait Wgsl {
    /// The type as WGSL writes it (`f32`, `vec3<f32>`, `array<Post, 16>`, a struct name).
    fn wgsl_type() -> String;
    /// Adds the WGSL structs this type needs to `declarations` (nothing for built-in types).
    fn declare(_declarations: &mut Declarations) {}
}

/// WGSL struct declarations, each struct once, in dependency order.
#[derive(Debug, Default)]
pub struct Declarations {
    declared: Vec<&'static str>,
    text: String,
}

impl Declarations {
    /// The declarations `T` needs, ready to prefix a shader.
    pub fn of<T: Wgsl>() -> String {
        let mut declarations = Declarations::default();
        T::declare(&mut declarations);
        declarations.into_text()
    }

    /// The declarations made so far.
    pub fn into_text(self) -> String {
        self.text
    }

    /// Declares struct `name` with `fields` (name, WGSL type) unless it is declared already.
    pub fn structure(&mut self, name: &'static str, fields: &[(&str, String)]) {
        if self.declared.contains(&name) {
            return;
        }
        self.declared.push(name);
        self.text.push_str(&format!("struct {name} {{\n"));
        for (field, ty) in fields {
            self.text.push_str(&format!("    {field}: {ty},\n"));
        }
        self.text.push_str("};\n\n");
    }
}

macro_rules! wgsl_scalar {
    ($($ty:ty => $name:literal),*) => {
        $(impl Wgsl for $ty {
            fn wgsl_type() -> String {
                $name.to_owned()
            }
        })*
    };
}
wgsl_scalar!(f32 => "f32", u32 => "u32", i32 => "i32");

impl<T: Wgsl, const N: usize> Wgsl for [T; N] {
    fn wgsl_type() -> String {
        format!("array<{}, {N}>", T::wgsl_type())
    }

    fn declare(declarations: &mut Declarations) {
        T::declare(declarations);
    }
}

/// `vecN<f32>`: a vector of the GPU blocks (encase lays out only types it knows; glam's are
/// foreign to both crates).
macro_rules! gpu_vector {
    ($($(#[$doc:meta])* $name:ident($n:literal) from $glam:ty;)*) => {
        $(
            $(#[$doc])*
            #[derive(Debug, Clone, Copy, PartialEq, Default)]
            pub struct $name(pub [f32; $n]);

            impl AsRef<[f32; $n]> for $name {
                fn as_ref(&self) -> &[f32; $n] {
                    &self.0
                }
            }

            impl AsMut<[f32; $n]> for $name {
                fn as_mut(&mut self) -> &mut [f32; $n] {
                    &mut self.0
                }
            }

            impl From<[f32; $n]> for $name {
                fn from(parts: [f32; $n]) -> $name {
                    $name(parts)
                }
            }

            impl From<$glam> for $name {
                fn from(v: $glam) -> $name {
                    $name(v.to_array())
                }
            }

            encase::impl_vector!($n, $name, f32; using AsRef AsMut From);

            impl Wgsl for $name {
                fn wgsl_type() -> String {
                    concat!("vec", $n, "<f32>").to_owned()
                }
            }
        )*
    };
}

gpu_vector! {
    /// `vec2<f32>`.
    Vec2f(2) from glam::Vec2;
    /// `vec3<f32>` (16-byte aligned in a block, 12 bytes long: a scalar may follow in its
    /// last 4 bytes).
    Vec3f(3) from glam::Vec3;
    /// `vec4<f32>`.
    Vec4f(4) from glam::Vec4;
}

/// `mat4x4<f32>`, column-major.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Mat4f(pub [[f32; 4]; 4]);

impl AsRef<[[f32; 4]; 4]> for Mat4f {
    fn as_ref(&self) -> &[[f32; 4]; 4] {
        &self.0
    }
}

impl AsMut<[[f32; 4]; 4]> for Mat4f {
    fn as_mut(&mut self) -> &mut [[f32; 4]; 4] {
        &mut self.0
    }
}

impl From<[[f32; 4]; 4]> for Mat4f {
    fn from(columns: [[f32; 4]; 4]) -> Mat4f {
        Mat4f(columns)
    }
}

impl From<glam::Mat4> for Mat4f {
    fn from(m: glam::Mat4) -> Mat4f {
        Mat4f(m.to_cols_array_2d())
    }
}

encase::impl_matrix!(4, 4, Mat4f, f32; using AsRef AsMut From);

impl Wgsl for Mat4f {
    fn wgsl_type() -> String {
        "mat4x4<f32>".to_owned()
    }
}

/// Declares a GPU parameter block: the Rust struct (laid out by `encase`) and its WGSL
/// declaration ([`Wgsl`]), from one list of named fields.
macro_rules! gpu_block {
    (
        $(#[$attr:meta])*
        pub struct $name:ident {
            $($(#[$field_attr:meta])* pub $field:ident: $ty:ty,)*
        }
    ) => {
        $(#[$attr])*
        #[derive(Debug, Clone, Copy, PartialEq, Default, encase::ShaderType)]
        pub struct $name {
            $($(#[$field_attr])* pub $field: $ty,)*
        }

        impl $crate::render::uniforms::Wgsl for $name {
            fn wgsl_type() -> String {
                stringify!($name).to_owned()
            }

            fn declare(declarations: &mut $crate::render::uniforms::Declarations) {
                $(<$ty as $crate::render::uniforms::Wgsl>::declare(declarations);)*
                declarations.structure(
                    stringify!($name),
                    &[$((stringify!($field), <$ty as $crate::render::uniforms::Wgsl>::wgsl_type())),*],
                );
            }
        }
    };
}
pub(crate) use gpu_block;

/// The bytes of `block` as the GPU reads a uniform of its type.
pub fn bytes<T: ShaderType + WriteInto>(block: &T) -> Vec<u8> {
    let mut buffer = encase::UniformBuffer::new(Vec::<u8>::new());
    // Writing into a growable Vec fails only for types encase cannot lay out, which the
    // derive rejects at compile time.
    buffer.write(block).expect("a uniform block fits a growable buffer");
    buffer.into_inner()
}

/// A read-only storage buffer holding `items` as a WGSL runtime-sized `array<T>` (at least one
/// item: a binding cannot be empty).
pub fn storage_buffer<T>(device: &wgpu::Device, label: &str, items: &Vec<T>) -> wgpu::Buffer
where
    Vec<T>: ShaderType + WriteInto,
{
    use wgpu::util::DeviceExt;
    let mut bytes = encase::StorageBuffer::new(Vec::<u8>::new());
    // Writing into a growable Vec fails only for types encase cannot lay out, which the
    // derive rejects at compile time.
    bytes.write(items).expect("a storage array fits a growable buffer");
    device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some(label),
        contents: &bytes.into_inner(),
        usage: wgpu::BufferUsages::STORAGE,
    })
}

/// The size in bytes of a `T` uniform.
pub fn size_of<T: ShaderType>() -> u64 {
    T::min_size().get()
}

/// Parses and validates WGSL `source` with naga (wgpu's shader front end), panicking with the
/// diagnostic: shader sources are composed from declarations, so tests check that they compile.
#[cfg(test)]
pub(crate) fn validate_wgsl(label: &str, source: &str) {
    let module =
        naga::front::wgsl::parse_str(source).unwrap_or_else(|e| panic!("{label}: {}", e.emit_to_string(source)));
    naga::valid::Validator::new(naga::valid::ValidationFlags::all(), naga::valid::Capabilities::all())
        .validate(&module)
        .unwrap_or_else(|e| panic!("{label}: {}", e.emit_to_string(source)));
}

#[cfg(test)]
mod tests {
    use super::*;

    gpu_block! {
        /// A test block: a vec3 with a scalar in its tail, an array of structs.
        pub struct Inner {
            pub colour: Vec3f,
            pub weight: f32,
        }
    }

    gpu_block! {
        /// The outer test block.
        pub struct Outer {
            pub scale: f32,
            pub items: [Inner; 2],
            pub transform: Mat4f,
        }
    }

    #[test]
    fn blocks_declare_their_wgsl_structs_once_in_dependency_order() {
        let wgsl = Declarations::of::<Outer>();
        assert_eq!(
            wgsl,
            "struct Inner {\n    colour: vec3<f32>,\n    weight: f32,\n};\n\n\
             struct Outer {\n    scale: f32,\n    items: array<Inner, 2>,\n    transform: mat4x4<f32>,\n};\n\n"
        );
    }

    #[test]
    fn blocks_are_laid_out_by_the_wgsl_uniform_rules() {
        let block = Outer {
            scale: 2.0,
            items: [
                Inner { colour: Vec3f([1.0, 2.0, 3.0]), weight: 4.0 },
                Inner { colour: Vec3f([5.0, 6.0, 7.0]), weight: 8.0 },
            ],
            transform: glam::Mat4::IDENTITY.into(),
        };
        let bytes = bytes(&block);
        let floats: Vec<f32> = bytes.chunks_exact(4).map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]])).collect();
        // `scale` then padding to the 16-byte array; each Inner is 16 bytes (the weight in the
        // vec3's tail); the matrix at offset 48.
        assert_eq!(bytes.len(), 48 + 64);
        assert_eq!(size_of::<Outer>(), 112);
        assert_eq!(floats[0], 2.0);
        assert_eq!(&floats[4..12], &[1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0]);
        assert_eq!(floats[12], 1.0);
        assert_eq!(floats[17], 1.0);
    }
}
