//! `gridrt bench`: one library call (`gridrt::request::bench::bench_files`), which writes the
//! outputs asked for, then the table printed.

use anyhow::Result;

use super::progress::Stages;
use super::BenchArgs;
use gridrt::request::bench::{bench_files, markdown, BenchOutputs, BenchRequest};

pub fn run(args: &BenchArgs, stages: &mut Stages) -> Result<()> {
    let results = bench_files(&args.request(), stages)?;
    print!("{}", markdown(&results));
    Ok(())
}

impl BenchArgs {
    /// The library's request for these arguments.
    fn request(&self) -> BenchRequest {
        BenchRequest {
            meshes: self.meshes.clone(),
            build: self.build.request(),
            backend: self.backend.choice(),
            views: self.views,
            width: self.width,
            height: self.height,
            ao_samples: self.ao_samples,
            ray_order: self.ray_order.order(),
            warmup: self.warmup,
            repeats: self.repeats,
            build_repeats: self.build_repeats,
            reference: self.reference.clone(),
            outputs: BenchOutputs {
                json: self.json.clone(),
                markdown: self.markdown.clone(),
                chart: self.chart.clone(),
                font: self.font.clone(),
            },
        }
    }
}
