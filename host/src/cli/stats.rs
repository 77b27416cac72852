//! `gridrt stats`: one library call (`gridrt::request::stats::stats_file`), then its table
//! or JSON printed.

use anyhow::Result;

use super::progress::Stages;
use super::StatsArgs;
use gridrt::request::stats::stats_file;

pub fn run(args: &StatsArgs, stages: &mut Stages) -> Result<()> {
    let s = stats_file(args.mesh.as_deref(), &args.build.request(), stages)?;
    if args.json {
        println!("{}", serde_json::to_string(&s)?);
        return Ok(());
    }
    println!(
        "{}: L = {}, {} base triangles, {} micro-triangles",
        s.mesh, s.levels, s.base_triangles, s.micro_triangles
    );
    for (label, r) in [("grid", &s.grid), ("triangles", &s.triangles)] {
        println!(
            "  {label:<10} {:>12} bytes  {:>6.2} B/triangle  build {:>9.4} s",
            r.bytes, r.bytes_per_triangle, r.build_seconds
        );
        for (part, bytes) in &r.parts {
            println!("    {part:<16} {bytes:>12}");
        }
    }
    println!(
        "  compression gain {:.2}x, construction gain {:.1}x",
        s.compression_gain, s.construction_gain
    );
    Ok(())
}
