//! Transfer-function search (Marks et al. 1997 design galleries; He et al. 1996): a TF
//! genome of primitives ([`genome`]), and design galleries that render a seeded pool of
//! genomes from several viewpoints in batched atlases, keep the K most dispersed by
//! greedy farthest-point selection on ΔE*uv, and lay them out by classical MDS
//! ([`gallery`]). Everything is seeded: the same seed, data and settings give the same
//! genomes and the same images.

pub mod adapt;
pub mod coverage;
pub mod gallery;
pub mod genetic;
pub mod genome;
