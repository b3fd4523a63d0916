//! Pointer events for the headless egui tests of the editors.

/// A press (`pressed`) or release of `button` at `pos`.
pub fn press(pos: egui::Pos2, pressed: bool, button: egui::PointerButton) -> egui::Event {
    egui::Event::PointerButton {
        pos,
        button,
        pressed,
        modifiers: egui::Modifiers::NONE,
    }
}
