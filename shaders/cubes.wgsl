// Instanced voxel cubes, generated from vertex_index (no vertex buffer): instance i is voxel i of the compacted
// list (two u32 per voxel: x | y << 16, z), vertex v is corner v % 6 of face v / 6. `vs_cube` reads the list and
// the colours from storage buffers; `vs_cube_attributes` gets the same two values as per-instance vertex
// attributes, for WebGL2, whose vertex shaders cannot read storage buffers. Faces are lit by a key and a
// fill directional light plus ambient, so all six face directions read differently, and their borders are
// darkened so single voxels stand out. A second pipeline draws the floor grid under the model, a third the
// source mesh translucently on top.

struct View {
    view_proj: mat4x4<f32>,
    // x: voxel size. Everything is drawn relative to the grid origin (the host keeps that in f64), so a mesh far
    // from the world origin keeps the precision of one at the origin.
    grid: vec4<f32>,
    color: vec4<f32>,
    mesh_color: vec4<f32>,
    // x: 1 when the target is not sRGB and the shader must encode; y: edge darkening strength (0 = off);
    // z: 1 to draw each voxel's own colour from `colours` instead of `color`; w: 1 to darken corners by the
    // ambient occlusion in `occlusion`.
    options: vec4<f32>,
    // The floor grid (render::Floor), in the drawing frame: the square's corners (w of `floor_min`: the up axis's
    // index; w of `floor_max`: the line spacing), and the phase that puts lines at world multiples of the spacing
    // (w: 1 when the eye is above the floor, 0 to hide it).
    floor_min: vec4<f32>,
    floor_max: vec4<f32>,
    floor_phase: vec4<f32>,
}

@group(0) @binding(0) var<uniform> view: View;
@group(0) @binding(1) var<storage, read> voxels: array<u32>;
// One sRGB RGBA8 colour per instance (r in the low byte), when options.z is 1.
@group(0) @binding(2) var<storage, read> colours: array<u32>;
// Ambient occlusion, two words per instance, when options.w is 1: 2 bits per face corner, face f's corner
// u + 2 v at bit (4 f + u + 2 v) * 2, from 0 (in a crease) to 3 (open); see render::ambient_occlusion.
@group(0) @binding(3) var<storage, read> occlusion: array<u32>;

struct CubeOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) @interpolate(flat) face: u32,
    @location(1) uv: vec2<f32>,
    @location(2) @interpolate(flat) albedo: vec3<f32>,
    // The face's four corner occlusions (1 = open), at uv (0, 0), (1, 0), (0, 1), (1, 1).
    @location(3) @interpolate(flat) ao: vec4<f32>,
}

@vertex
fn vs_cube(@builtin(vertex_index) vi: u32, @builtin(instance_index) ii: u32) -> CubeOut {
    var colour = vec3<f32>(0.0);
    if view.options.z != 0.0 {
        colour = unpack4x8unorm(colours[ii]).rgb;
    }
    var ao = vec2<u32>(0xffffffffu);
    if view.options.w != 0.0 {
        ao = vec2<u32>(occlusion[2u * ii], occlusion[2u * ii + 1u]);
    }
    return cube_vertex(vi, vec2<u32>(voxels[2u * ii], voxels[2u * ii + 1u]), colour, ao);
}

@vertex
fn vs_cube_attributes(
    @builtin(vertex_index) vi: u32,
    @location(0) voxel: vec2<u32>,
    @location(1) colour: vec4<f32>,
    @location(2) ao: vec2<u32>,
) -> CubeOut {
    return cube_vertex(vi, voxel, colour.rgb, ao);
}

// Corner `vi` of the cube of the voxel packed as `voxel` (x | y << 16, z), with its sRGB colour `colour` (used
// when options.z is 1) and its ambient occlusion words `ao` (used when options.w is 1).
fn cube_vertex(vi: u32, voxel: vec2<u32>, colour: vec3<f32>, ao: vec2<u32>) -> CubeOut {
    let cell = vec3<f32>(f32(voxel.x & 0xffffu), f32(voxel.x >> 16u), f32(voxel.y));
    let face = vi / 6u;
    let axis = face / 2u;
    let positive = face % 2u == 1u;
    // Quad corners as two triangles, counter-clockwise seen from outside for the positive face; the negative
    // face uses the mirrored order.
    var ccw = array<vec2<f32>, 6>(
        vec2<f32>(0.0, 0.0), vec2<f32>(1.0, 0.0), vec2<f32>(1.0, 1.0),
        vec2<f32>(0.0, 0.0), vec2<f32>(1.0, 1.0), vec2<f32>(0.0, 1.0),
    );
    var cw = array<vec2<f32>, 6>(
        vec2<f32>(0.0, 0.0), vec2<f32>(1.0, 1.0), vec2<f32>(1.0, 0.0),
        vec2<f32>(0.0, 0.0), vec2<f32>(0.0, 1.0), vec2<f32>(1.0, 1.0),
    );
    var uv = ccw[vi % 6u];
    if !positive {
        uv = cw[vi % 6u];
    }
    var local = vec3<f32>(0.0);
    local[axis] = select(0.0, 1.0, positive);
    local[(axis + 1u) % 3u] = uv.x;
    local[(axis + 2u) % 3u] = uv.y;
    let world = (cell + local) * view.grid.xyz;
    var out: CubeOut;
    out.clip = view.view_proj * vec4<f32>(world, 1.0);
    out.face = face;
    out.uv = uv;
    out.albedo = view.color.rgb;
    if view.options.z != 0.0 {
        out.albedo = decode(colour);
    }
    let bit = face * 8u;
    let corners = (select(ao.x, ao.y, bit >= 32u) >> (bit % 32u)) & 0xffu;
    out.ao = vec4<f32>(vec4<u32>(corners, corners >> 2u, corners >> 4u, corners >> 6u) & vec4<u32>(3u)) / 3.0;
    return out;
}

fn face_normal(face: u32) -> vec3<f32> {
    var n = vec3<f32>(0.0);
    n[face / 2u] = select(-1.0, 1.0, face % 2u == 1u);
    return n;
}

// The sRGB transfer function's inverse: voxel colours are stored encoded, lighting works in linear light.
fn decode(c: vec3<f32>) -> vec3<f32> {
    let lo = c / 12.92;
    let hi = pow((c + 0.055) / 1.055, vec3<f32>(2.4));
    return select(hi, lo, c <= vec3<f32>(0.04045));
}

fn encode(linear: vec3<f32>) -> vec3<f32> {
    if view.options.x == 0.0 {
        return linear;
    }
    // The sRGB transfer function, for targets the hardware does not encode.
    let lo = linear * 12.92;
    let hi = 1.055 * pow(linear, vec3<f32>(1.0 / 2.4)) - 0.055;
    return select(hi, lo, linear <= vec3<f32>(0.0031308));
}

@fragment
fn fs_cube(in: CubeOut) -> @location(0) vec4<f32> {
    let n = face_normal(in.face);
    let key = normalize(vec3<f32>(0.5, 0.75, 0.3));
    let fill = normalize(vec3<f32>(-0.7, -0.2, -0.3));
    let light = 0.12 + 0.8 * max(dot(n, key), 0.0) + 0.32 * max(dot(n, fill), 0.0);
    // Distance to the nearest face border in pixels, from the screen-space rate of change of uv. Faces only a
    // few pixels across would be all border, so the darkening fades out as cubes get small on screen.
    let rate = max(fwidth(in.uv), vec2<f32>(1e-6));
    let border = min(in.uv, 1.0 - in.uv) / rate;
    let strength = view.options.y * (1.0 - smoothstep(0.1, 0.3, max(rate.x, rate.y)));
    let edge = 1.0 - strength * (1.0 - smoothstep(0.0, 1.5, min(border.x, border.y)));
    // The corners' occlusion interpolated across the face, as voxel editors shade creases.
    let open = mix(mix(in.ao.x, in.ao.y, in.uv.x), mix(in.ao.z, in.ao.w, in.uv.x), in.uv.y);
    let occlusion = mix(1.0, 0.4 + 0.6 * open, view.options.w);
    return vec4<f32>(encode(in.albedo * light * edge * occlusion), 1.0);
}

struct FloorOut {
    @builtin(position) clip: vec4<f32>,
    // The point of the floor, in the drawing frame.
    @location(0) position: vec3<f32>,
}

@vertex
fn vs_floor(@builtin(vertex_index) vi: u32) -> FloorOut {
    var corners = array<vec2<f32>, 6>(
        vec2<f32>(0.0, 0.0), vec2<f32>(1.0, 0.0), vec2<f32>(1.0, 1.0),
        vec2<f32>(0.0, 0.0), vec2<f32>(1.0, 1.0), vec2<f32>(0.0, 1.0),
    );
    let up = u32(view.floor_min.w);
    let uv = corners[vi % 6u];
    var p = view.floor_min.xyz;
    p[(up + 1u) % 3u] = mix(view.floor_min[(up + 1u) % 3u], view.floor_max[(up + 1u) % 3u], uv.x);
    p[(up + 2u) % 3u] = mix(view.floor_min[(up + 2u) % 3u], view.floor_max[(up + 2u) % 3u], uv.y);
    var out: FloorOut;
    out.position = p;
    // Seen from below, the floor would hide the model: every corner goes outside the clip volume instead.
    out.clip = select(vec4<f32>(2.0, 2.0, 2.0, 1.0), view.view_proj * vec4<f32>(p, 1.0), view.floor_phase.w != 0.0);
    return out;
}

// Anti-aliased lines about a pixel wide where a coordinate of `coord` is an integer: 1 on a line, 0 between.
// Lines closer together than a few pixels fade out instead of turning into a moiré.
fn grid_lines(coord: vec2<f32>) -> f32 {
    let rate = max(fwidth(coord), vec2<f32>(1e-6));
    let distance = abs(fract(coord - 0.5) - 0.5) / rate;
    let line = 1.0 - min(min(distance.x, distance.y), 1.0);
    return line * (1.0 - smoothstep(0.12, 0.35, max(rate.x, rate.y)));
}

@fragment
fn fs_floor(in: FloorOut) -> @location(0) vec4<f32> {
    let up = u32(view.floor_min.w);
    let a = (up + 1u) % 3u;
    let b = (up + 2u) % 3u;
    // In spacings from the world origin (up to a whole number of major lines), so lines sit at world multiples.
    let world = vec2<f32>(in.position[a] + view.floor_phase[a], in.position[b] + view.floor_phase[b]);
    let coord = world / view.floor_max.w;
    let strength = max(0.22 * grid_lines(coord), 0.5 * grid_lines(coord / 10.0));
    // Fades toward the square's rim, so the floor has no hard edge.
    let centre = 0.5 * (view.floor_min.xyz + view.floor_max.xyz);
    let half = 0.5 * (view.floor_max[a] - view.floor_min[a]);
    let r = length(vec2<f32>(in.position[a] - centre[a], in.position[b] - centre[b])) / half;
    let fade = 1.0 - smoothstep(0.55, 1.0, r);
    return vec4<f32>(encode(vec3<f32>(0.62, 0.66, 0.72)), strength * fade);
}

struct MeshOut {
    @builtin(position) clip: vec4<f32>,
}

@vertex
fn vs_mesh(@location(0) position: vec3<f32>) -> MeshOut {
    var out: MeshOut;
    out.clip = view.view_proj * vec4<f32>(position, 1.0);
    return out;
}

@fragment
fn fs_mesh() -> @location(0) vec4<f32> {
    return vec4<f32>(encode(view.mesh_color.rgb), view.mesh_color.a);
}
