//! The plugins' own widgets (feature `ui`): what a plugin shows in the window above the
//! widgets generated from its parameter spec. Each lives in its plugin's folder and is
//! named on the plugin's line of the `builtin_plugins!` list, so the window never
//! matches plugin ids.

use std::collections::HashMap;
use std::sync::OnceLock;

use crate::params::ParamValues;

/// Draws extra widgets for a plugin's parameters, with the document's volumes where
/// the window has them (a label plugin lists its label volume's labels); true when a
/// value changed.
pub type CustomUi =
    fn(&mut egui::Ui, &mut ParamValues, Option<&vwb_render::inputs::Volumes<'_>>) -> bool;

/// The own widgets of the built-in plugin `plugin_id`, if it has any.
pub fn custom_ui(plugin_id: &str) -> Option<CustomUi> {
    static ALL: OnceLock<HashMap<String, CustomUi>> = OnceLock::new();
    ALL.get_or_init(|| super::builtin_widgets().into_iter().collect())
        .get(plugin_id)
        .copied()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_plugins_that_declare_widgets_have_them() {
        let r = crate::builtin_registry();
        let with: Vec<&str> = r
            .plugins()
            .iter()
            .map(|p| p.id())
            .filter(|id| custom_ui(id).is_some())
            .collect();
        assert_eq!(with, ["clip.labels", "classify.labels", "shade.dos"]);
        assert!(custom_ui("no.such.plugin").is_none());
    }
}
