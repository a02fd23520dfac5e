//! Preprocessing of plant models, done once per model and cached by content hash (in the
//! process, and on disk across restarts): higher level primitives (HLP, thesis 4.2) that the
//! NPR passes use for silhouette and hatching parametrization and for abstract shading, and
//! the levels of detail drawn at a distance; the implicit-surface illumination of foliage
//! (`implicit`, Luft et al. 2007) and leaf shape maps (`leaf_shape`, thesis 4.1); and the
//! terrain's chunks with their own levels (`terrain_lod`).

pub mod cache;
pub mod creases;
pub mod hlp;
pub mod implicit;
pub mod leaf_shape;
pub mod leaves;
pub mod lod;
pub mod masses;
pub mod substitution;
pub mod terrain_lod;
