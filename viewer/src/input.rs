//! egui's pointer, wheel, touch and keys, as the rig's [`Input`].
//!
//! Drag orbits (or, flying, looks); right or middle drag, or shift and
//! drag, pans; the wheel and a pinch zoom toward the cursor; two fingers
//! pan; WASD or the arrows (Q and E down and up) fly; F switches flying.

use egui::{Key, PointerButton, Rect, Response};

use crate::rig::{Input, ZOOM_PER_STEP};

/// Reads this frame's input over the scene (`response` covers `rect`).
/// `flying` is switched by F.
pub fn read_input(ui: &egui::Ui, response: &Response, rect: Rect, flying: &mut bool) -> Input {
    let ppp = ui.ctx().pixels_per_point();
    let mut input = Input::default();
    let shift = ui.input(|i| i.modifiers.shift);
    let drag = response.drag_delta() * ppp;
    let touch = ui.input(|i| i.multi_touch());
    if touch.is_none() {
        if response.dragged_by(PointerButton::Secondary)
            || response.dragged_by(PointerButton::Middle)
            || (shift && response.dragged_by(PointerButton::Primary))
        {
            input.pan = [drag.x, drag.y];
        } else if response.dragged_by(PointerButton::Primary) {
            input.rotate = [drag.x, drag.y];
        }
    }
    let centre = rect.center();
    let cursor = response.hover_pos().unwrap_or(centre);
    let offset = (cursor - centre) * ppp;
    if let Some(t) = touch {
        let pan = t.translation_delta * ppp;
        input.pan = [pan.x, pan.y];
        if t.zoom_delta != 1.0 && t.zoom_delta > 0.0 {
            // A pinch that doubles the span halves the distance.
            input.zoom = (f64::from(t.zoom_delta).ln() / ZOOM_PER_STEP) as f32;
            let at = (t.center_pos - centre) * ppp;
            input.zoom_at = [at.x, at.y];
        }
    } else if response.hovered() {
        let scroll = ui.input(|i| i.smooth_scroll_delta.y);
        if scroll != 0.0 {
            // One wheel notch is about 50 points of scroll.
            input.zoom = scroll / 50.0;
            input.zoom_at = [offset.x, offset.y];
        }
    }
    if ui.memory(|m| m.focused().is_none()) {
        ui.input(|i| {
            if i.key_pressed(Key::F) {
                *flying = !*flying;
            }
            let axis = |plus: &[Key], minus: &[Key]| {
                let down = |keys: &[Key]| keys.iter().any(|k| i.key_down(*k));
                f32::from(u8::from(down(plus))) - f32::from(u8::from(down(minus)))
            };
            input.fly = [
                axis(&[Key::W, Key::ArrowUp], &[Key::S, Key::ArrowDown]),
                axis(&[Key::D, Key::ArrowRight], &[Key::A, Key::ArrowLeft]),
                axis(&[Key::E], &[Key::Q]),
            ];
        });
    }
    input
}
