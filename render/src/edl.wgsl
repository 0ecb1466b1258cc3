// Eye-dome lighting (Boucheny's, as Potree draws it): a full-screen pass
// after the scene's, which darkens each pixel by how far its neighbours
// stand in front of it, in log depth, so edges, creases and depth steps
// show without normals; next to nothing drawn, a point is outlined.
//
// The depth buffer holds near / z (reversed Z, 0 infinitely far): the
// difference of two pixels' log depths is the difference of the logs of
// what the buffer holds, whatever `near` is.
//
// The pass multiplies the frame by what it outputs (blend: dst * src), so
// it reads only depth, never the color it changes.

struct Edl {
    // Strength (Potree's default: 1), radius in pixels, unused, unused.
    params: vec4<f32>,
};

@group(0) @binding(0) var depth: texture_2d<f32>;
@group(0) @binding(1) var<uniform> edl: Edl;
// Nearest, so each texel is read as it is. (Read with `textureLoad`,
// without a sampler, WebGL2 finds a depth texture incomplete and reads 0.)
@group(0) @binding(2) var nearest: sampler;

@vertex
fn vs(@builtin(vertex_index) i: u32) -> @builtin(position) vec4<f32> {
    // One triangle over the whole screen.
    let x = f32(i32(i & 1u) * 4 - 1);
    let y = f32(i32(i >> 1u) * 4 - 1);
    return vec4<f32>(x, y, 0.0, 1.0);
}

// What the depth buffer holds at `p`, clamped to the frame.
fn stored(p: vec2<i32>) -> f32 {
    let size = vec2<i32>(textureDimensions(depth));
    let q = clamp(p, vec2<i32>(0), size - vec2<i32>(1));
    let uv = (vec2<f32>(q) + vec2<f32>(0.5)) / vec2<f32>(size);
    return textureSampleLevel(depth, nearest, uv, 0.0).x;
}

@fragment
fn fs(@builtin(position) frag: vec4<f32>) -> @location(0) vec4<f32> {
    let p = vec2<i32>(frag.xy);
    let here = stored(p);
    let radius = edl.params.y;
    var sum = 0.0;
    for (var k = 0; k < 8; k++) {
        let angle = f32(k) * 0.7853982;
        let offset = vec2<i32>(round(vec2<f32>(cos(angle), sin(angle)) * radius));
        let there = stored(p + offset);
        if there > 0.0 {
            if here > 0.0 {
                // log2(z_here) - log2(z_there), z = near / stored.
                sum += max(0.0, log2(there) - log2(here));
            } else {
                sum += 100.0;
            }
        }
    }
    let shade = exp(-sum / 8.0 * 300.0 * edl.params.x);
    return vec4<f32>(shade, shade, shade, 1.0);
}
