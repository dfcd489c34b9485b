//! Pictures: top-down scenario frames and animations drawn to scale (`scene`), and line charts
//! (training curves, ego time series: `charts`). PNG and GIF through plotters' bitmap backend;
//! text in DejaVu Sans, bundled (`assets/fonts`), so no system font is needed.

pub mod charts;
pub mod episode;
pub mod scene;
pub mod timespace;

use std::sync::Once;

/// A picture could not be made.
#[derive(Debug, thiserror::Error)]
pub enum RenderError {
    /// Drawing or encoding failed (plotters' message).
    #[error("drawing {path}: {message}")]
    Draw {
        /// The output file.
        path: String,
        /// What went wrong.
        message: String,
    },
    /// Nothing to draw.
    #[error("{0}")]
    Empty(String),
}

/// The font family every picture uses.
pub const FONT: &str = "sans-serif";

static FONT_BYTES: &[u8] = include_bytes!("../../assets/fonts/DejaVuSans.ttf");

/// Registers the bundled font once per process.
pub(crate) fn register_font() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        plotters::style::register_font(FONT, plotters::style::FontStyle::Normal, FONT_BYTES)
            .unwrap_or_else(|_| panic!("the bundled DejaVu Sans is a valid TrueType font"));
    });
}

/// Wraps a plotters error with the file it was drawing.
pub(crate) fn draw_error(path: &std::path::Path) -> impl Fn(&dyn std::fmt::Display) -> RenderError + '_ {
    move |e| RenderError::Draw {
        path: path.display().to_string(),
        message: e.to_string(),
    }
}
