//! A PNG chart of the three ratios the method is judged by, per mesh: compression gain,
//! construction gain and ray tracing impact.

use std::path::Path;

use crate::error::{error, Result};
use plotters::prelude::*;
use plotters::style::{register_font, FontStyle};

/// Where a sans-serif font is looked for when none is given (Debian's fonts-dejavu-core).
pub const DEFAULT_FONT: &str = "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf";

fn short_name(mesh: &str) -> String {
    Path::new(mesh)
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| mesh.to_string())
}

/// One mesh's bars: its three ratios, the impact for primary and AO rays.
pub struct ChartRow<'a> {
    pub mesh: &'a str,
    pub compression_gain: f64,
    pub construction_gain: f64,
    pub rt_impact_primary: f64,
    pub rt_impact_ao: f64,
}

/// Draws `results`, measured on `backend`, to the PNG `path` in the TrueType `font`.
pub fn write_chart(results: &[ChartRow], backend: &str, path: &Path, font: &Path) -> Result<()> {
    let bytes = std::fs::read(font).map_err(|e| {
        error!(
            Input,
            "{}: cannot read font for the chart: {}",
            font.display(),
            crate::files::io_reason(&e)
        )
    })?;
    register_font("sans-serif", FontStyle::Normal, Box::leak(bytes.into_boxed_slice()))
        .map_err(|_| error!(Input, "{}: not a usable TrueType font", font.display()))?;
    let names: Vec<String> = results.iter().map(|r| short_name(r.mesh)).collect();
    let panels: [(&str, Vec<(f64, RGBColor)>); 3] = [
        (
            "compression gain (x)",
            results.iter().map(|r| (r.compression_gain, BLUE)).collect(),
        ),
        (
            "construction gain (x)",
            results.iter().map(|r| (r.construction_gain, GREEN)).collect(),
        ),
        (
            "RT impact (%): primary, AO",
            results
                .iter()
                .flat_map(|r| [(r.rt_impact_primary, RED), (r.rt_impact_ao, MAGENTA)])
                .collect(),
        ),
    ];
    let title = format!("gridrt vs triangle BVH, {backend} backend");
    let backend = BitMapBackend::new(path, (1500, 500)).into_drawing_area();
    backend
        .fill(&WHITE)
        .map_err(|e| error!(Output, "{}: {e}", path.display()))?;
    let backend = backend
        .titled(&title, ("sans-serif", 24))
        .map_err(|e| error!(Output, "{}: {e}", path.display()))?;
    for (area, (label, bars)) in backend.split_evenly((1, 3)).iter().zip(&panels) {
        let per_mesh = bars.len() / names.len().max(1);
        let top = bars.iter().map(|b| b.0).fold(0.0, f64::max) * 1.15 + 1e-9;
        let bottom = bars.iter().map(|b| b.0).fold(0.0, f64::min).min(0.0) * 1.15;
        let n = names.len() as f64;
        let mut chart = ChartBuilder::on(area)
            .caption(*label, ("sans-serif", 18))
            .margin(12)
            .x_label_area_size(10)
            .y_label_area_size(50)
            .build_cartesian_2d(-0.5..n - 0.5, bottom..top)
            .map_err(|e| error!(Output, "{}: {e}", path.display()))?;
        chart
            .configure_mesh()
            .disable_x_mesh()
            .x_labels(0)
            .draw()
            .map_err(|e| error!(Output, "{}: {e}", path.display()))?;
        // Bars of one mesh side by side around its position.
        let width = 0.7 / per_mesh as f64;
        chart
            .draw_series(bars.iter().enumerate().map(|(k, &(value, color))| {
                let x = (k / per_mesh) as f64 - 0.35 + (k % per_mesh) as f64 * width;
                Rectangle::new([(x + 0.02, 0.0), (x + width - 0.02, value)], color.mix(0.8).filled())
            }))
            .map_err(|e| error!(Output, "{}: {e}", path.display()))?;
        // Values above the bars, mesh names at the foot.
        chart
            .draw_series(bars.iter().enumerate().map(|(k, &(value, _))| {
                let x = (k / per_mesh) as f64 - 0.35 + (k % per_mesh) as f64 * width;
                Text::new(
                    format!("{value:.1}"),
                    (x + 0.03, value.max(0.0) + (top - bottom) * 0.04),
                    ("sans-serif", 13),
                )
            }))
            .map_err(|e| error!(Output, "{}: {e}", path.display()))?;
        chart
            .draw_series(names.iter().enumerate().map(|(i, name)| {
                Text::new(
                    name.clone(),
                    (i as f64 - 0.3, bottom + (top - bottom) * 0.02),
                    ("sans-serif", 15),
                )
            }))
            .map_err(|e| error!(Output, "{}: {e}", path.display()))?;
    }
    backend
        .present()
        .map_err(|e| error!(Output, "{}: cannot write the chart: {e}", path.display()))?;
    Ok(())
}
