//! Preprocessing of plant models, done once per model and cached by content hash (in the
//! process, and on disk across restarts): higher level primitives (HLP, thesis 4.2) that the
//! NPR passes use for silhouette and hatching parametrization and for abstract shading, and
//! the levels of detail drawn at a distance.

pub mod cache;
pub mod hlp;
pub mod lod;
