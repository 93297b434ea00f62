//! The `vdbphoton` command line. Parsing and printing only: the work is in
//! the library.

mod args;
mod render;
mod reporter;

use args::{Cli, Command, Kind};
use clap::Parser;
use std::process::ExitCode;
use std::time::Instant;
use vdbphoton::vdb::{self, AnyGrid};
use vdbphoton::{generate, Error, Result};

fn run(cli: Cli) -> Result<()> {
    match cli.command {
        Command::Render(a) => render::render(a, false),
        Command::View(a) => render::render(a, true),
        Command::Merge {
            out,
            inputs,
            preview,
            exposure,
            view,
            denoise,
        } => {
            let m = vdbphoton::merge::merge(
                &out,
                &inputs,
                &vdbphoton::merge::MergeOptions {
                    preview: preview.as_deref(),
                    exposure,
                    view,
                    denoise,
                },
            )?;
            for p in &m.outputs {
                println!("Saved: '{}'", p.display());
            }
            let groups: Vec<String> = m
                .groups
                .iter()
                .map(|(seed, n)| format!("{n} with seed {seed}"))
                .collect();
            eprintln!(
                "merged {} inputs ({}) into {} x {}, {} spp",
                inputs.len(),
                groups.join(", "),
                m.width,
                m.height,
                m.spp
            );
            Ok(())
        }
        Command::ExportVol { file, out, grid } => {
            let s = vdbphoton::export::export_vol(&file, &out, &grid)?;
            let [x, y, z] = s.resolution;
            eprintln!(
                "wrote {} ({x} x {y} x {z} voxels, world box {:?} .. {:?})",
                out.display(),
                s.world_box[0].map(|v| v as f32),
                s.world_box[1].map(|v| v as f32)
            );
            Ok(())
        }
        Command::Integrators => {
            for reg in vdbphoton::integrator::REGISTRY {
                println!("{:8} {}", reg.name, reg.about);
                for (key, doc) in reg.keys {
                    println!("         [render.{}] {key}: {doc}", reg.name);
                }
            }
            println!(
                "{:8} the renderer chooses from the scene (the header's vdbphoton/integrator says which)",
                vdbphoton::scene::AUTO_INTEGRATOR
            );
            Ok(())
        }
        Command::Compare {
            image,
            reference,
            diff,
            side_by_side,
            exposure,
            view,
        } => {
            let a = vdbphoton::image::read_exr_rgb(&image)?;
            let b = vdbphoton::image::read_exr_rgb(&reference)?;
            let m = vdbphoton::image::compare(&a, &b)?;
            println!(
                "mean {:.6}  reference mean {:.6}  ratio {:.5}  RMSE {:.6}  relMSE {:.3e}  PSNR {:.2} dB",
                m.mean_a, m.mean_b, m.mean_ratio, m.rmse, m.rel_mse, m.psnr
            );
            if let Some(d) = diff {
                let scale = vdbphoton::image::write_diff_png(&d, &a, &b)?;
                eprintln!(
                    "wrote {} (full colour at |difference| = {scale:.4})",
                    d.display()
                );
            }
            if let Some(p) = side_by_side {
                let name = |p: &std::path::Path| {
                    p.file_name()
                        .map_or(String::new(), |n| n.to_string_lossy().into_owned())
                };
                vdbphoton::image::write_side_by_side(
                    &p,
                    &a,
                    &b,
                    &name(&image),
                    &name(&reference),
                    &m,
                    exposure,
                    view,
                )?;
                eprintln!("wrote {}", p.display());
            }
            Ok(())
        }
        Command::Info { files, grid, json } => {
            // Every file is shown; one that cannot be read is an error
            // line, the others still print, and the exit code says so.
            let mut failed = 0;
            let mut out = Vec::new();
            for f in &files {
                match vdbphoton::inspect::report(f, grid.as_deref(), json) {
                    Ok(vdbphoton::inspect::Report::Json(v)) => out.push(v),
                    Ok(vdbphoton::inspect::Report::Text(t)) => print!("{t}"),
                    Err(e) if files.len() > 1 => {
                        eprintln!("vdbphoton: error: {}", one_line(&e));
                        failed += 1;
                    }
                    Err(e) => return Err(e),
                }
            }
            if json {
                let v = if files.len() == 1 {
                    out.pop().unwrap_or_default()
                } else {
                    serde_json::Value::Array(out)
                };
                println!("{}", serde_json::to_string_pretty(&v).unwrap_or_default());
            }
            if failed > 0 {
                return Err(Error::Argument(format!(
                    "{failed} of {} files could not be read",
                    files.len()
                )));
            }
            Ok(())
        }
        Command::Generate {
            kind,
            out,
            res,
            seed,
        } => {
            let t0 = Instant::now();
            let grids = match kind {
                Kind::Cloud => vec![AnyGrid::Float(generate::cloud(res, seed)?)],
                Kind::Plume => generate::plume(res, seed)?,
            };
            vdb::write_vdb(&out, &grids)?;
            let voxels: u64 = grids.iter().map(|g| g.active_voxel_count()).sum();
            eprintln!(
                "wrote {} ({} grid{}, {} active voxels) in {:.2} s",
                out.display(),
                grids.len(),
                if grids.len() == 1 { "" } else { "s" },
                voxels,
                t0.elapsed().as_secs_f64()
            );
            Ok(())
        }
    }
}

fn main() -> ExitCode {
    let cli = match Cli::try_parse() {
        Ok(c) => c,
        Err(e) => {
            use clap::error::ErrorKind;
            if matches!(
                e.kind(),
                ErrorKind::DisplayHelp
                    | ErrorKind::DisplayVersion
                    | ErrorKind::DisplayHelpOnMissingArgumentOrSubcommand
            ) {
                let _ = e.print();
                return ExitCode::SUCCESS;
            }
            // One line, and the exit code of every other bad input.
            let text = e.to_string();
            let first = text
                .lines()
                .find(|l| !l.trim().is_empty())
                .unwrap_or("invalid arguments");
            eprintln!(
                "vdbphoton: {} (see vdbphoton --help)",
                first.trim_start_matches("error: ").trim()
            );
            return ExitCode::from(1);
        }
    };
    vdbphoton::interrupt::install();
    match run(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("vdbphoton: error: {}", one_line(&e));
            ExitCode::from(e.exit_code())
        }
    }
}

fn one_line(e: &Error) -> String {
    e.to_string().replace('\n', " ")
}
