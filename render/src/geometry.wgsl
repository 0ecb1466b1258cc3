// Triangles and color-cube faces (farfield client renderer, cube hierarchy).
//
// Positions arrive camera-relative in world axes (f64 on the CPU, then
// f32), and are rotated into view space here. The projection is the splat
// shader's: reversed Z with an infinite far plane, clip = (x / tan_half_x,
// y / tan_half_y, near, depth).
//
// Shading must equal the cube builder's (farfield_protocol::shading): base
// * (ambient + diffuse * max(n . l, 0)), the normal turned toward the
// viewer (two-sided), so cubes and geometry match where they meet.

struct Frame {
    right: vec4<f32>,
    up: vec4<f32>,
    forward: vec4<f32>,
    // 1 / tan_half_x, 1 / tan_half_y, near, unused
    proj: vec4<f32>,
    // Unit direction toward the light, world space.
    light: vec4<f32>,
    // ambient, diffuse, unused, unused
    params: vec4<f32>,
    // A window of the view (a cache's rectangle): clip xy * window.xy +
    // window.zw * w; (1, 1, 0, 0) for the whole view.
    window: vec4<f32>,
};

@group(0) @binding(0) var<uniform> frame: Frame;

fn clip_of(p: vec3<f32>) -> vec4<f32> {
    let x = dot(p, frame.right.xyz);
    let y = dot(p, frame.up.xyz);
    let depth = dot(p, frame.forward.xyz);
    let xy = vec2<f32>(x * frame.proj.x, y * frame.proj.y) * frame.window.xy
        + frame.window.zw * depth;
    return vec4<f32>(xy, frame.proj.z, depth);
}

fn shade(base: vec3<f32>, normal: vec3<f32>, toward_viewer: vec3<f32>) -> vec3<f32> {
    var n = normal;
    if dot(n, n) < 1e-30 {
        n = toward_viewer;
    }
    n = normalize(n);
    if dot(n, toward_viewer) < 0.0 {
        n = -n;
    }
    return base * (frame.params.x + frame.params.y * max(dot(n, frame.light.xyz), 0.0));
}

struct TriangleIn {
    @location(0) position: vec3<f32>,
    // World-space normal; w = 1 when the vertex has one.
    @location(1) normal: vec4<f32>,
    @location(2) color: vec4<f32>,
};

struct TriangleOut {
    @builtin(position) position: vec4<f32>,
    @location(0) rel: vec3<f32>,
    @location(1) normal: vec4<f32>,
    @location(2) color: vec3<f32>,
};

@vertex
fn vs_triangle(v: TriangleIn) -> TriangleOut {
    var out: TriangleOut;
    out.position = clip_of(v.position);
    out.rel = v.position;
    out.normal = v.normal;
    out.color = v.color.rgb;
    return out;
}

// A placed prototype's corner: the prototype's own frame, carried by the
// instance's linear part and its camera-relative translation.
struct InstanceIn {
    @location(3) x_axis: vec3<f32>,
    @location(4) y_axis: vec3<f32>,
    @location(5) z_axis: vec3<f32>,
    @location(6) translation: vec3<f32>,
};

@vertex
fn vs_instanced(v: TriangleIn, i: InstanceIn) -> TriangleOut {
    let p = i.x_axis * v.position.x + i.y_axis * v.position.y + i.z_axis * v.position.z
        + i.translation;
    var out: TriangleOut;
    out.position = clip_of(p);
    out.rel = p;
    // Prototypes are flat-shaded: no stored normal to carry.
    out.normal = vec4<f32>(0.0);
    out.color = v.color.rgb;
    return out;
}

@fragment
fn fs_triangle(i: TriangleOut) -> @location(0) vec4<f32> {
    // Flat: the geometric normal from the position's derivatives, taken
    // before choosing: WGSL allows derivatives only in uniform control
    // flow (Chrome's compiler refuses them inside the branch; naga does not
    // check).
    let flat = cross(dpdx(i.rel), dpdy(i.rel));
    let n = select(flat, i.normal.xyz, i.normal.w > 0.5);
    return vec4<f32>(shade(i.color, n, -i.rel), 1.0);
}

struct FaceIn {
    // The cube's minimum corner (camera-relative) and edge.
    @location(0) min_corner: vec3<f32>,
    @location(1) edge: f32,
    // 0..5: +x, -x, +y, -y, +z, -z
    @location(2) face: u32,
    // Premultiplied RGBA.
    @location(3) rgba: vec4<f32>,
};

struct FaceOut {
    @builtin(position) position: vec4<f32>,
    @location(0) @interpolate(flat) rgba: vec4<f32>,
};

@vertex
fn vs_face(@builtin(vertex_index) vi: u32, f: FaceIn) -> FaceOut {
    let axis = f.face / 2u;
    var offset = vec3<f32>(0.0, 0.0, 0.0);
    offset[axis] = select(0.0, 1.0, f.face % 2u == 0u);
    offset[(axis + 1u) % 3u] = f32(vi & 1u);
    offset[(axis + 2u) % 3u] = f32(vi >> 1u);
    var out: FaceOut;
    out.position = clip_of(f.min_corner + offset * f.edge);
    out.rgba = f.rgba;
    return out;
}

// Coverage threshold (1995): a face that is drawn is opaque.
@fragment
fn fs_face_opaque(i: FaceOut) -> @location(0) vec4<f32> {
    return vec4<f32>(i.rgba.rgb / max(i.rgba.a, 1e-6), 1.0);
}

// Alpha as transparency (1996): blended premultiplied, back to front.
@fragment
fn fs_face_blended(i: FaceOut) -> @location(0) vec4<f32> {
    return i.rgba;
}
