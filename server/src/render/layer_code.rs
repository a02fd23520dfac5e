//! Layer codes: the top 8 bits of an object ID in the G-buffer's ID target
//! ([`super::gbuffer::ID_FORMAT`]), telling which layer of the scene a pixel shows. The code
//! of a layer is also its style slot (see [`super::style::FrameStyle::slots`]); the shaders
//! decode it in `style_slot` of `shaders/post_common.wgsl`.

use super::style::STYLE_SLOTS;

/// The layer code of an object ID: 0 the background, 1 the terrain, `i + 2` vegetation layer
/// `i`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct LayerCode(u32);

impl LayerCode {
    /// Where nothing was drawn (object ID 0); its style slot is the base style's.
    pub const BACKGROUND: LayerCode = LayerCode(0);
    /// The terrain.
    pub const TERRAIN: LayerCode = LayerCode(1);
    /// The code of the first vegetation layer; layer `i` has code `FIRST_VEGETATION + i`.
    pub const FIRST_VEGETATION: u32 = 2;
    /// Bits of an object ID below its layer code: the object index + 1 (see
    /// [`super::gbuffer::object_id`]).
    pub const SHIFT: u32 = 24;
    /// The object-index bits of an object ID.
    pub const INDEX_MASK: u32 = (1 << Self::SHIFT) - 1;
    /// Vegetation layers that can have style slots of their own.
    pub const VEGETATION_SLOTS: usize = STYLE_SLOTS - Self::FIRST_VEGETATION as usize;

    /// The code of vegetation layer `index` (in the scene's layer order).
    pub const fn vegetation(index: usize) -> LayerCode {
        LayerCode(Self::FIRST_VEGETATION + index as u32)
    }

    /// The layer code of an object ID.
    pub const fn of_object_id(object_id: u32) -> LayerCode {
        LayerCode(object_id >> Self::SHIFT)
    }

    /// The code as a number (as the ID target stores it).
    pub const fn code(self) -> u32 {
        self.0
    }

    /// The style slot of a layer with a style slot of its own (the code, when below
    /// [`STYLE_SLOTS`]).
    pub const fn own_slot(self) -> Option<usize> {
        let code = self.0 as usize;
        if code < STYLE_SLOTS { Some(code) } else { None }
    }

    /// The style slot the layer is drawn with: its own, or the base slot 0 (the background's)
    /// beyond the slots.
    pub const fn slot(self) -> usize {
        match self.own_slot() {
            Some(slot) => slot,
            None => LayerCode::BACKGROUND.0 as usize,
        }
    }

    /// The layer-code constants as the post shaders read them (`style_slot` in
    /// `shaders/post_common.wgsl`).
    pub fn wgsl_constants() -> String {
        format!(
            "const STYLE_SLOTS: u32 = {STYLE_SLOTS}u;\nconst LAYER_SHIFT: u32 = {}u;\nconst LAYER_BACKGROUND: u32 = {}u;\nconst LAYER_TERRAIN: u32 = {}u;\n\n",
            Self::SHIFT,
            Self::BACKGROUND.0,
            Self::TERRAIN.0
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn codes_and_slots() {
        assert_eq!(LayerCode::BACKGROUND.code(), 0);
        assert_eq!(LayerCode::TERRAIN.code(), 1);
        assert_eq!(LayerCode::vegetation(0).code(), 2);
        assert_eq!(LayerCode::vegetation(3), LayerCode::of_object_id((5 << 24) | 17));
        assert_eq!(LayerCode::INDEX_MASK, 0x00FF_FFFF);
        assert_eq!(LayerCode::vegetation(13).slot(), 15);
        assert_eq!(LayerCode::vegetation(14).own_slot(), None);
        assert_eq!(LayerCode::vegetation(14).slot(), 0);
        assert_eq!(LayerCode::VEGETATION_SLOTS, 14);
    }
}
