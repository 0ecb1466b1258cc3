// Splats as instanced screen-aligned quads (farfield client renderer).
//
// Instances arrive camera-relative in view space: center = (right, up,
// depth along forward). The projection is reversed-Z with an infinite far
// plane: clip = (x / tan_half_x, y / tan_half_y, near, depth), so the depth
// buffer holds near / depth (1 at the near plane, towards 0 far away).
// A splat is never drawn smaller than MIN_RADIUS_PX pixels: a disc of
// radius 0.75 px always covers a pixel center, so a cut of 1-pixel splats
// (the traversal's default threshold) has no holes.

struct Frame {
    // 1 / tan_half_x, 1 / tan_half_y, near, MIN_RADIUS_PX in view units
    // at depth 1 (0.75 * 2 tan_half_y / height)
    proj: vec4<f32>,
    // Unit direction toward the light, world space (for splat normals).
    light_world: vec4<f32>,
    // The same in view space: x right, y up, z toward the viewer (spheres).
    light_view: vec4<f32>,
    // x: square kernel (0), round (1) or paraboloid (2); y: two-sided
    // lighting
    flags: vec4<f32>,
};

@group(0) @binding(0) var<uniform> frame: Frame;

struct SplatIn {
    @location(0) center: vec3<f32>,
    @location(1) radius: f32,
    // World-space normal; w = 1 when present, 0 for a sphere impostor.
    @location(2) normal: vec4<f32>,
    @location(3) color: vec4<f32>,
};

struct VsOut {
    @builtin(position) position: vec4<f32>,
    // Position in the quad, -1..1 on both axes, +y up.
    @location(0) quad: vec2<f32>,
    @location(1) @interpolate(flat) normal: vec4<f32>,
    @location(2) @interpolate(flat) color: vec3<f32>,
    // The center's depth and the quad's radius, view units (paraboloids).
    @location(3) @interpolate(flat) depth_radius: vec2<f32>,
};

struct FsOut {
    @location(0) color: vec4<f32>,
    @builtin(frag_depth) depth: f32,
};

@vertex
fn vs_main(@builtin(vertex_index) vi: u32, s: SplatIn) -> VsOut {
    // A four-vertex triangle strip per instance.
    let q = vec2<f32>(f32(vi & 1u) * 2.0 - 1.0, f32(vi >> 1u) * 2.0 - 1.0);
    // Offsetting in view space at the center's depth: perspective-correct size.
    let radius = max(s.radius, frame.proj.w * s.center.z);
    let p = s.center.xy + q * radius;
    var out: VsOut;
    out.position = vec4<f32>(p.x * frame.proj.x, p.y * frame.proj.y, frame.proj.z, s.center.z);
    out.quad = q;
    out.normal = s.normal;
    out.color = s.color.rgb;
    out.depth_radius = vec2<f32>(s.center.z, radius);
    return out;
}

// The splat's lit color, or a discard outside its footprint.
fn shade(in: VsOut) -> vec4<f32> {
    let r2 = dot(in.quad, in.quad);
    let sphere = in.normal.w < 0.5;
    if (sphere || frame.flags.x > 0.5) && r2 > 1.0 {
        discard;
    }
    var lambert: f32;
    if sphere {
        let n = vec3<f32>(in.quad, sqrt(max(1.0 - r2, 0.0)));
        lambert = max(dot(n, frame.light_view.xyz), 0.0);
    } else {
        let d = dot(normalize(in.normal.xyz), frame.light_world.xyz);
        lambert = select(max(d, 0.0), abs(d), frame.flags.y > 0.5);
    }
    return vec4<f32>(in.color * (0.3 + 0.7 * lambert), 1.0);
}

// Flat splats: the depth the quad was rasterized at (early depth tests
// stay on).
@fragment
fn fs_main(in: VsOut) -> @location(0) vec4<f32> {
    return shade(in);
}

// Paraboloids: nearer toward the middle by up to the radius, never past
// the near plane.
@fragment
fn fs_paraboloid(in: VsOut) -> FsOut {
    var out: FsOut;
    out.color = shade(in);
    let r2 = dot(in.quad, in.quad);
    let z = max(in.depth_radius.x - in.depth_radius.y * (1.0 - r2), frame.proj.z);
    out.depth = frame.proj.z / z;
    return out;
}
