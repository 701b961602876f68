//! Input in one vocabulary for the window and for replay scripts: pointer events in window pixels and
//! key chords such as `"ctrl+z"`.

use winit::keyboard::{Key, ModifiersState, NamedKey};

/// A mouse button.
pub use super::session::Button;

/// One input event.
#[derive(Debug, Clone, PartialEq)]
pub enum Input {
    /// Pointer moved to a window position.
    Move([f32; 2]),
    /// Button pressed at a window position.
    Press(Button, [f32; 2]),
    /// Button released.
    Release(Button),
    /// Wheel, in lines (positive zooms in).
    Scroll(f32),
    /// Key pressed (chord name) or released (`pressed = false`, no modifiers).
    Key { chord: String, pressed: bool },
}

/// Normalises a chord such as `"Ctrl+Shift+Z"` to `"ctrl+shift+z"` (modifiers in that order).
pub fn normalize_chord(chord: &str) -> String {
    let parts: Vec<String> = chord
        .split('+')
        .map(|p| p.trim().to_lowercase())
        .filter(|p| !p.is_empty())
        .collect();
    let has = |m: &str| parts.iter().any(|p| p == m);
    let key = parts
        .iter()
        .rev()
        .find(|p| !matches!(p.as_str(), "ctrl" | "shift" | "alt"))
        .cloned()
        .unwrap_or_default();
    let mut out = String::new();
    for m in ["ctrl", "shift", "alt"] {
        if has(m) {
            out.push_str(m);
            out.push('+');
        }
    }
    out.push_str(&key);
    out
}

/// The key name of a winit key (`None` for keys the editor does not use).
pub fn key_name(key: &Key) -> Option<String> {
    match key {
        Key::Character(c) => Some(c.to_lowercase()),
        Key::Named(n) => Some(
            match n {
                NamedKey::Delete => "delete",
                NamedKey::Backspace => "backspace",
                NamedKey::Escape => "escape",
                NamedKey::Space => "space",
                NamedKey::Shift => "shift",
                NamedKey::Control => "ctrl",
                _ => return None,
            }
            .to_string(),
        ),
        _ => None,
    }
}

/// The chord for a key with the current modifiers.
pub fn chord(name: &str, mods: ModifiersState) -> String {
    let mut s = String::new();
    if mods.control_key() && name != "ctrl" {
        s.push_str("ctrl+");
    }
    if mods.shift_key() && name != "shift" {
        s.push_str("shift+");
    }
    if mods.alt_key() {
        s.push_str("alt+");
    }
    s.push_str(name);
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn chords_normalise() {
        assert_eq!(normalize_chord("Shift+Ctrl+Z"), "ctrl+shift+z");
        assert_eq!(normalize_chord("delete"), "delete");
    }
}
