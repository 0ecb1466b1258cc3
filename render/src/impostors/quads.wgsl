// Cached images on their quads (hierarchical image caching). A quad's four
// corners arrive camera-relative (f64 on the CPU, then f32) with the
// image's texel rectangle in the atlas; the image is premultiplied (made
// on a transparent background), so it is blended with "one, one minus
// source alpha" and leaves no halo.
//
// This file is appended to geometry.wgsl when the module is made
// (resources.rs), so `frame` (window included: quads drawn into a
// parent's cache use its narrowed frustum) and `clip_of` are the
// triangles' own.

@group(1) @binding(0) var atlas: texture_2d<f32>;
@group(1) @binding(1) var atlas_sampler: sampler;

struct QuadIn {
    // Top-left, top-right, bottom-left, bottom-right.
    @location(0) c0: vec3<f32>,
    @location(1) c1: vec3<f32>,
    @location(2) c2: vec3<f32>,
    @location(3) c3: vec3<f32>,
    // u0, v0, u1, v1 in the atlas (normalized).
    @location(4) uv: vec4<f32>,
};

struct QuadOut {
    @builtin(position) position: vec4<f32>,
    @location(0) uv: vec2<f32>,
    // Where on the quad, 0 to 1 across and down (for the outline).
    @location(1) across: vec2<f32>,
};

@vertex
fn vs_quad(@builtin(vertex_index) i: u32, q: QuadIn) -> QuadOut {
    var p = q.c0;
    var uv = q.uv.xy;
    var across = vec2<f32>(0.0, 0.0);
    if i == 1u {
        p = q.c1;
        uv = vec2<f32>(q.uv.z, q.uv.y);
        across = vec2<f32>(1.0, 0.0);
    } else if i == 2u {
        p = q.c2;
        uv = vec2<f32>(q.uv.x, q.uv.w);
        across = vec2<f32>(0.0, 1.0);
    } else if i == 3u {
        p = q.c3;
        uv = q.uv.zw;
        across = vec2<f32>(1.0, 1.0);
    }
    var out: QuadOut;
    out.position = clip_of(p);
    out.uv = uv;
    out.across = across;
    return out;
}

@fragment
fn fs_quad(i: QuadOut) -> @location(0) vec4<f32> {
    return textureSample(atlas, atlas_sampler, i.uv);
}

// The outline a viewer shows around each cache (`SplatStyle::outline_caches`):
// opaque magenta within OUTLINE_PX screen pixels of the quad's edge, the
// image inside. Only the final frame uses it, never a cache being made.
const OUTLINE_PX: f32 = 1.5;
const OUTLINE: vec4<f32> = vec4<f32>(1.0, 0.0, 1.0, 1.0);

@fragment
fn fs_quad_outlined(i: QuadOut) -> @location(0) vec4<f32> {
    let image = textureSample(atlas, atlas_sampler, i.uv);
    // Distance to the nearest edge in pixels: the quad coordinate's
    // distance over its change per pixel (never 0 on a drawn fragment,
    // but guarded).
    let per_px = max(fwidth(i.across), vec2<f32>(1e-6));
    let to_edge = min(i.across, vec2<f32>(1.0) - i.across) / per_px;
    if min(to_edge.x, to_edge.y) < OUTLINE_PX {
        return OUTLINE;
    }
    return image;
}
