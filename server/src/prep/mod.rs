//! Preprocessing of plant models, done once per model and cached by content hash: higher level
//! primitives (HLP, thesis 4.2) that the NPR passes use for silhouette and hatching
//! parametrization and for abstract shading.

pub mod hlp;
