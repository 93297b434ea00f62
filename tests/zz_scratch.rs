use vdbphoton::film::{Film, Region};
use vdbphoton::integrator::{render_pass, Integrator, PathIntegrator, PhotonIntegrator};
use vdbphoton::scene::SceneDesc;
use vdbphoton::world::World;

fn layer(f: &Film, name: &str) -> Vec<f32> {
    let img = f.to_image().unwrap();
    if name == "L" {
        return img.pixels().iter().flat_map(|p| [p.x, p.y, p.z]).collect();
    }
    img.layer(name).unwrap().data().to_vec()
}

#[test]
fn noise_breakdown() {
    let scene = std::env::var("SCRATCH_SCENE")
        .unwrap_or("../shared/data/reference/cloud96_sun.toml".into());
    let passes: u32 = std::env::var("SCRATCH_PASSES")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(4);
    let photons: u32 = std::env::var("SCRATCH_PHOTONS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(200000);
    let path = std::env::var("SCRATCH_PATH").is_ok();
    let mut desc = SceneDesc::load(&scene).unwrap();
    desc.render.photon.photons = photons;
    let world = World::load(&desc).unwrap();
    let (w, h) = (desc.render.width, desc.render.height);
    let mut films = vec![];
    for seed in [1u64, 2] {
        let mut integ: Box<dyn Integrator> = if path {
            Box::new(PathIntegrator::new(desc.render.max_bounces))
        } else {
            Box::new(
                PhotonIntegrator::new(&world, desc.render.photon, desc.render.max_bounces, seed)
                    .unwrap(),
            )
        };
        let mut film = Film::new(w, h, Region::full(w, h), true);
        let t = std::time::Instant::now();
        for p in 0..passes {
            integ.begin_pass(&world, p);
            render_pass(&world, integ.as_ref(), &mut film, seed, p, &|_, _| {});
        }
        eprintln!("seed {seed}: {:.2} s", t.elapsed().as_secs_f64());
        films.push(film);
    }
    for name in ["L", "direct", "indirect", "emission"] {
        let (a, b) = (layer(&films[0], name), layer(&films[1], name));
        let n = a.len() as f64;
        let mse: f64 = a
            .iter()
            .zip(&b)
            .map(|(x, y)| ((x - y) as f64).powi(2))
            .sum::<f64>()
            / n
            / 2.0;
        let m: f64 = a
            .iter()
            .zip(&b)
            .map(|(x, y)| ((x + y) as f64) * 0.5)
            .sum::<f64>()
            / n;
        eprintln!(
            "{name}: mean {m:.5}  per-render variance {mse:.3e}  rel {:.3e}",
            mse / (m * m).max(1e-30)
        );
    }
}
