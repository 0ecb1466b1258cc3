//! The cost model of `UpdateNode` (section 2): what drawing a triangle,
//! making a cache of `n` pixels and drawing a cached quad cost on this
//! machine. The paper established them "experimentally on each platform";
//! here the renderer measures them at start-up
//! (`farfield_render::Renderer::measure_impostor_costs`) and the values
//! are reported with every run. [`CostModel::UNMEASURED`] is only a
//! placeholder for a traversal that has not been told yet.
//!
//! One term the paper does not have: a quad's cost per pixel it covers.
//! On the paper's machine texture-mapped fill was nearly free beside
//! geometry; on a CPU rasterizer (llvmpipe) a large blended quad costs
//! tens of times a small one, and a model that calls every quad equal
//! caches nodes whose quads cost more than their geometry.

/// Milliseconds per unit of work.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct CostModel {
    /// Drawing one triangle as geometry.
    pub ms_per_triangle: f64,
    /// Making a cache: drawing its contents aside and copying them, per
    /// pixel of its rectangle (the contents' own cost is added apart).
    pub ms_per_cache_pixel: f64,
    /// A cache's fixed cost (a pass and a copy), whatever its size.
    pub ms_per_cache: f64,
    /// Drawing one cached quad, whatever its size.
    pub ms_per_quad: f64,
    /// Drawing a cached quad, per pixel it covers.
    pub ms_per_quad_pixel: f64,
    /// Whether the values were measured on this machine.
    pub measured: bool,
}

impl CostModel {
    /// Orders of magnitude of a desktop GPU, until measured.
    pub const UNMEASURED: Self = Self {
        ms_per_triangle: 2e-6,
        ms_per_cache_pixel: 2e-6,
        ms_per_cache: 0.05,
        ms_per_quad: 0.002,
        ms_per_quad_pixel: 1e-7,
        measured: false,
    };

    /// Making a cache of `pixels` whose contents cost `contents_ms`.
    pub fn create_ms(&self, pixels: u64, contents_ms: f64) -> f64 {
        self.ms_per_cache + self.ms_per_cache_pixel * pixels as f64 + contents_ms
    }

    /// Drawing a cached quad of `pixels`.
    pub fn quad_ms(&self, pixels: u64) -> f64 {
        self.ms_per_quad + self.ms_per_quad_pixel * pixels as f64
    }

    /// Drawing `triangles` as geometry.
    pub fn geometry_ms(&self, triangles: u64) -> f64 {
        self.ms_per_triangle * triangles as f64
    }
}

impl Default for CostModel {
    fn default() -> Self {
        Self::UNMEASURED
    }
}
