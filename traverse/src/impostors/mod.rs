//! Hierarchical image caching (Shade et al. 1996): far subtrees of a BSP
//! drawn from cached images on single quads while an error bound holds.
//!
//! The paper's section 3, the error metric and the safety zones that say
//! how long a cache stays valid, is [`safety`]. The cache itself
//! (`UpdateCaches`, `UpdateNode`, the atlas) and the BSP walk come as the
//! kind grows.

pub mod safety;
