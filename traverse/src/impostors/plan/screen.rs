//! A node's rectangle on the screen and its quad's corners in the world.

use farfield_protocol::camera::View;
use glam::DVec3;

/// The pixels the corners cover: x, y (top-left, y down; either may be
/// off the screen), width, height, rounded outward; `None` unless every
/// corner is in front of the eye and the rectangle is no larger than the
/// viewport (the paper's rule: a cache is drawn at the screen's
/// resolution, and a part off the screen is drawn into it too).
pub fn screen_rect(view: &View, corners: &[DVec3]) -> Option<[i32; 4]> {
    let (w, h) = (f64::from(view.width), f64::from(view.height));
    let (mut x0, mut y0, mut x1, mut y1) =
        (f64::INFINITY, f64::INFINITY, -f64::INFINITY, -f64::INFINITY);
    for &c in corners {
        let rel = c - view.eye;
        let depth = rel.dot(view.forward);
        if depth.is_nan() || depth <= 0.0 {
            return None;
        }
        let x = (rel.dot(view.right) / (depth * view.tan_half_x) + 1.0) * 0.5 * w;
        let y = (1.0 - rel.dot(view.up) / (depth * view.tan_half_y)) * 0.5 * h;
        x0 = x0.min(x);
        x1 = x1.max(x);
        y0 = y0.min(y);
        y1 = y1.max(y);
    }
    let (x0, y0, x1, y1) = (x0.floor(), y0.floor(), x1.ceil(), y1.ceil());
    let (rw, rh) = ((x1 - x0).max(1.0), (y1 - y0).max(1.0));
    // In view and no larger than it: the corner is within a screen of it.
    if !(rw <= w && rh <= h && x0.abs() <= 4.0 * w && y0.abs() <= 4.0 * h) {
        return None;
    }
    Some([x0 as i32, y0 as i32, rw as i32, rh as i32])
}

/// The rectangle's corners on the plane at `depth` along the view:
/// top-left, top-right, bottom-left, bottom-right.
pub fn quad_corners(view: &View, rect: [i32; 4], depth: f64) -> [DVec3; 4] {
    let (w, h) = (f64::from(view.width.max(1)), f64::from(view.height.max(1)));
    let [x, y, rw, rh] = rect.map(f64::from);
    let at = |px: f64, py: f64| {
        let nx = px / w * 2.0 - 1.0;
        let ny = 1.0 - py / h * 2.0;
        view.eye
            + (view.forward
                + view.right * (nx * view.tan_half_x)
                + view.up * (ny * view.tan_half_y))
                * depth
    };
    [at(x, y), at(x + rw, y), at(x, y + rh), at(x + rw, y + rh)]
}
