use super::npy::{parse_header_dict, read_npy_header, HeaderDict, NPY_PREAMBLE_LEN};
use super::order::{packets_pay, sample_may_pay};
use super::*;
use glam::DVec3;
use std::fmt::Write as _;
use zeroset_primitives::{Interval, Ray};

/// A source of in-memory rays that fails when asked for chunk `fail_at`.
struct FailingRays {
    rays: Vec<QueryRay>,
    taken: usize,
    chunk: usize,
    fail_at: Option<usize>,
}

impl RaySource for FailingRays {
    fn read_chunk(&mut self, max: usize, out: &mut Vec<QueryRay>) -> Result<bool, QueryError> {
        out.clear();
        if self.fail_at == Some(self.chunk) {
            return Err(QueryError {
                path: "rays".into(),
                location: format!("chunk {}", self.chunk),
                message: "unreadable".into(),
            });
        }
        self.chunk += 1;
        let end = (self.taken + max).min(self.rays.len());
        out.extend_from_slice(&self.rays[self.taken..end]);
        self.taken = end;
        Ok(end < self.rays.len())
    }
}

/// A sink keeping the rows it is given, that fails when given chunk `fail_at`.
#[derive(Default)]
struct KeptRows {
    rows: Vec<QueryHit>,
    chunks: usize,
    fail_at: Option<usize>,
    finished: bool,
}

impl HitSink for KeptRows {
    fn write_chunk(&mut self, _scene: &Scene, hits: &[QueryHit]) -> std::io::Result<()> {
        if self.fail_at == Some(self.chunks) {
            return Err(std::io::Error::other("disk full"));
        }
        self.chunks += 1;
        self.rows.extend_from_slice(hits);
        Ok(())
    }

    fn finish(&mut self) -> std::io::Result<()> {
        self.finished = true;
        Ok(())
    }
}

/// The batch loop, which reads the next chunk and writes the last one while it traces one,
/// writes and reports as if it took the chunks one after the other: every row in order (on
/// one thread and on three), the rows of the chunks before an unreadable one written and its
/// error returned, and a write error returned before the read error of a later chunk.
#[test]
fn the_batch_loop_writes_and_fails_in_chunk_order() {
    let scene = Scene::from_ron(
        "Scene(camera: (), objects: [(shape: Sphere(center: (0, 0, 0), radius: 1))])",
        "t.ron",
    )
    .unwrap();
    let n = 2 * CHUNK_RAYS + 1000;
    let rays: Vec<QueryRay> = (0..n)
        .map(|i| {
            let a = i as f64 * 0.618_033_988_749_895;
            QueryRay {
                ray: Ray::new(DVec3::new(a.sin() * 1.5, a.cos() * 1.5, -3.0), DVec3::Z),
                range: Interval::POSITIVE,
            }
        })
        .collect();
    let expected = trace_batch(&scene, &rays);
    let source = |fail_at| FailingRays {
        rays: rays.clone(),
        taken: 0,
        chunk: 0,
        fail_at,
    };
    for threads in [1, 3] {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        let mut sink = KeptRows::default();
        let counts = pool
            .install(|| run_batch(&scene, &mut source(None), &mut sink))
            .unwrap();
        assert_eq!(counts.rays, n as u64);
        assert_eq!(counts.hits, expected.iter().filter(|h| h.hit.is_some()).count() as u64);
        assert!(sink.finished && sink.chunks == 3);
        assert!(sink.rows == expected, "{threads} threads: rows in order");
        // the third chunk unreadable: the first two written, not finished
        let mut sink = KeptRows::default();
        let error = pool
            .install(|| run_batch(&scene, &mut source(Some(2)), &mut sink))
            .unwrap_err();
        assert_eq!(error.to_string(), "rays:chunk 2: unreadable");
        assert!(!sink.finished && sink.rows[..] == expected[..2 * CHUNK_RAYS]);
        // the second chunk's write fails before the third is found unreadable
        let mut sink = KeptRows {
            fail_at: Some(1),
            ..KeptRows::default()
        };
        let error = pool
            .install(|| run_batch(&scene, &mut source(Some(2)), &mut sink))
            .unwrap_err();
        assert_eq!(error.to_string(), "disk full");
        assert!(!sink.finished && sink.rows[..] == expected[..CHUNK_RAYS]);
    }
}

/// Rays handed to the scene together ([`trace_many_for`]) get exactly the answers they get
/// one by one, `uncertain` flags included: a lone object (the batch handed to it in one
/// call), a lone `Function` whose budget of 4 evaluations runs out on the rays through its
/// sphere (flagged ray by ray), three objects, and a lone mesh; in each, some directions of
/// the first 256 rays 10⁻³⁰⁰ or 10³⁰⁰ long (rescaled, so that batch is not handed over). Each scene takes random rays
/// and a camera's rays in pixel order (70 wide, so some runs of 8 straddle two rows): the
/// camera's runs of 8 pointing alike are handed over as packets, the others together.
#[test]
fn rays_traced_together_equal_rays_traced_one_by_one() {
    use rand::{Rng, SeedableRng};
    let dir = tempfile::tempdir().unwrap();
    let mesh_path = dir.path().join("ball.obj");
    let (vertices, triangles) = zeroset_primitives::testing::icosphere(3);
    let mut obj = String::new();
    for v in &vertices {
        writeln!(obj, "v {} {} {}", v[0], v[1], v[2]).unwrap();
    }
    for t in &triangles {
        writeln!(obj, "f {} {} {}", t[0] + 1, t[1] + 1, t[2] + 1).unwrap();
    }
    std::fs::write(&mesh_path, obj).unwrap();
    let scenes = [
        "Scene(camera: (), objects: [(shape: Sphere(center: (0, 0, 0), radius: 1))])".to_string(),
        "Scene(camera: (), objects: [(shape: Function(phi: \"sqrt(x^2 + y^2 + z^2) - 1\", \
         min: (-2, -2, -2), max: (2, 2, 2), budget: 4))])"
            .to_string(),
        "Scene(camera: (), objects: [(shape: Sphere(center: (0, 0, 0), radius: 1)), \
         (shape: Box(min: (2, -1, -1), max: (3, 1, 1))), (shape: Plane(normal: (0, 1, 0), point: (0, -2, 0)))])"
            .to_string(),
        format!(
            "Scene(camera: (), objects: [(shape: Mesh(path: {:?}))])",
            mesh_path.to_str().unwrap()
        ),
    ];
    // only in the first 256 rays: a batch of 256 with one such ray is traced ray by ray
    let scaled = |i: usize| match (i < 256, i % 97) {
        (true, 0) => 1e-300,
        (true, 1) => 1e300,
        _ => 1.0,
    };
    let mut rng = rand::rngs::StdRng::seed_from_u64(14);
    let random: Vec<QueryRay> = (0..3000)
        .map(|i| {
            let o = DVec3::new(rng.random_range(-3.0..3.0), rng.random_range(-3.0..3.0), -4.0);
            let aim = DVec3::new(rng.random_range(-1.5..1.5), rng.random_range(-1.5..1.5), 0.0);
            QueryRay {
                ray: Ray::new(o, (aim - o) * scaled(i)),
                range: Interval::POSITIVE,
            }
        })
        .collect();
    let (width, height) = (70, 50);
    let camera: Vec<QueryRay> = (0..width * height)
        .map(|i| {
            let (x, y) = ((i % width) as f64, (i / width) as f64);
            let d = DVec3::new((x + 0.5) / width as f64 - 0.5, 0.5 - (y + 0.5) / height as f64, 2.4);
            QueryRay {
                ray: Ray::new(DVec3::new(0.1, 0.2, -4.0), d * scaled(i)),
                range: Interval::POSITIVE,
            }
        })
        .collect();
    // most of the camera's runs of 8 are packets, none of the random rays'
    let packets = |rays: &[QueryRay]| {
        let rays: Vec<Ray> = rays.iter().map(|q| q.ray).collect();
        rays.chunks(zeroset_primitives::PACKET)
            .filter(|run| crate::trace::packet::coherent(run, crate::trace::packet::PACKET_COS))
            .count()
    };
    let (camera_packets, random_packets) = (packets(&camera), packets(&random));
    assert!(
        camera_packets > 350 && random_packets == 0,
        "{camera_packets}, {random_packets}"
    );
    for (which, text) in scenes.iter().enumerate() {
        let scene = Scene::from_ron(text, "t.ron").unwrap();
        for (kind, rays) in [("random", &random), ("camera", &camera)] {
            let one_by_one: Vec<QueryHit> = rays.iter().map(|q| trace_one(&scene, q)).collect();
            let mut work = TraceWork::default();
            let mut together = vec![MISS; rays.len()];
            for (rays, answers) in rays.chunks(256).zip(together.chunks_mut(256)) {
                trace_many_for(&scene, rays, ANSWER, &mut work, answers);
            }
            assert_eq!(together, one_by_one, "scene {which}, {kind} rays");
            assert_eq!(trace_batch(&scene, rays), one_by_one, "scene {which}, {kind} rays");
            let hits = one_by_one.iter().filter(|a| a.hit.is_some()).count();
            let uncertain = one_by_one.iter().filter(|a| a.uncertain).count();
            assert!(hits > 300, "scene {which}, {kind} rays: {hits} hits");
            assert_eq!(
                uncertain > 100,
                which == 1,
                "scene {which}, {kind} rays: {uncertain} uncertain"
            );
        }
    }
}

/// Tracing in the coherent order gives every ray the same answer as the input order, in
/// input order, and the order is a permutation.
#[test]
fn sorted_order_gives_the_same_answers() {
    use rand::{Rng, SeedableRng};
    let scene = Scene::from_ron(
        "Scene(camera: (), objects: [(shape: Sphere(center: (0, 0, 0), radius: 1)), \
         (shape: Box(min: (2, -1, -1), max: (3, 1, 1))), (shape: Plane(normal: (0, 1, 0), point: (0, -2, 0)))])",
        "t.ron",
    )
    .unwrap();
    let mut rng = rand::rngs::StdRng::seed_from_u64(3);
    let rays: Vec<QueryRay> = (0..5000)
        .map(|_| {
            let o = DVec3::new(
                rng.random_range(-4.0..4.0),
                rng.random_range(-1.5..4.0),
                rng.random_range(-4.0..4.0),
            );
            let d = DVec3::new(
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
            );
            QueryRay {
                ray: Ray::new(o, d),
                range: Interval::new(0.0, f64::INFINITY),
            }
        })
        .collect();
    let mut order = coherent_order(&rays);
    assert_ne!(order, (0..5000).collect::<Vec<u32>>(), "random rays get reordered");
    order.sort_unstable();
    assert_eq!(order, (0..5000).collect::<Vec<u32>>());
    // random rays: sorted neighbours point anywhere, so the batch is traced as given
    assert!(!packets_pay(&rays, &coherent_order(&rays)));
    let input = trace_batch_in(&scene, &rays, RayOrder::Input);
    let sorted = trace_batch_in(&scene, &rays, RayOrder::Sorted);
    assert!(input.iter().filter(|h| h.hit.is_some()).count() > 1000);
    assert_eq!(input, sorted);
    // four cameras' rays, shuffled: sorting gathers each camera's neighbouring rays into
    // packets, which are traced together and give the same answers
    let mut views: Vec<QueryRay> = (0..4000)
        .map(|i| {
            let eye = DVec3::new(f64::from(i % 4) - 1.5, 0.5, -6.0);
            let (u, v) = (f64::from(i / 4 % 40) / 40.0 - 0.5, f64::from(i / 160) / 25.0 - 0.5);
            QueryRay {
                ray: Ray::new(eye, DVec3::new(u * 0.8, v * 0.8, 1.0)),
                range: Interval::new(0.0, f64::INFINITY),
            }
        })
        .collect();
    for k in (1..views.len()).rev() {
        views.swap(k, rng.random_range(0..=k));
    }
    assert!(packets_pay(&views, &coherent_order(&views)));
    // judged on a sample first: many random rays are turned down before any sort, many
    // cameras' shuffled rays (a sample of one in ten) are still found coherent
    let many_random: Vec<QueryRay> = rays.iter().cycle().take(40_000).copied().collect();
    assert!(!sample_may_pay(&many_random));
    let mut many_views: Vec<QueryRay> = (0..40_000)
        .map(|i| {
            let eye = DVec3::new(f64::from(i % 4) - 1.5, 0.5, -6.0);
            let (u, v) = (f64::from(i / 4 % 100) / 100.0 - 0.5, f64::from(i / 400) / 100.0 - 0.5);
            QueryRay {
                ray: Ray::new(eye, DVec3::new(u * 0.8, v * 0.8, 1.0)),
                range: Interval::new(0.0, f64::INFINITY),
            }
        })
        .collect();
    for k in (1..many_views.len()).rev() {
        many_views.swap(k, rng.random_range(0..=k));
    }
    assert!(sample_may_pay(&many_views) && sample_may_pay(&views));
    let input = trace_batch_in(&scene, &views, RayOrder::Input);
    let sorted = trace_batch_in(&scene, &views, RayOrder::Sorted);
    assert!(input.iter().filter(|h| h.hit.is_some()).count() > 1000);
    assert_eq!(input, sorted);
}

fn origins(rays: &[QueryRay]) -> Vec<f64> {
    rays.iter().map(|r| r.ray.origin.x).collect()
}

#[test]
fn first_line_is_a_ray_unless_it_is_the_documented_header() {
    let bom = "\u{feff}1,0,-5,0,0,1\n2,0,-5,0,0,1\n";
    assert_eq!(origins(&parse_rays(bom, "r").unwrap()), [1.0, 2.0]);
    let spaced = " 1 , 0, -5, 0, 0, 1 \n2,0,-5,0,0,1\n";
    assert_eq!(origins(&parse_rays(spaced, "r").unwrap()), [1.0, 2.0]);
    let header = "\u{feff}ox, oy, oz, dx, dy, dz, tmin, tmax\n1,0,-5,0,0,1,0,9\n";
    assert_eq!(origins(&parse_rays(header, "r").unwrap()), [1.0]);
    for (text, needle) in [
        ("1;0;-5;0;0;1\n", "r:1: fields are separated by commas"),
        ("1,0,-5,0,0,1,\n", "r:1: field 7 is empty (a trailing comma?)"),
        ("1 0 -5 0 0 1\n", "r:1: field 1 `1 0 -5 0 0 1` is not a number"),
        ("x,y,z,dx,dy,dz\n1,0,-5,0,0,1\n", "r:1: field 1 `x`"),
        (
            "1,0,-5,0,0,1\nox,oy,oz,dx,dy,dz\n",
            "r:2: a header line is allowed only before",
        ),
    ] {
        let err = parse_rays(text, "r").unwrap_err().to_string();
        assert!(err.starts_with(needle), "{text:?}: {err}");
    }
}

#[test]
fn chunks_keep_line_numbers_and_order() {
    let mut text = String::from("# comment\n");
    for i in 0..10 {
        let _ = writeln!(text, "{i},0,0,0,0,1");
    }
    text.push_str("bad\n");
    let mut source = CsvRays::new(text.as_bytes(), "r");
    let mut chunk = Vec::new();
    let mut seen = Vec::new();
    let err = loop {
        match source.read_chunk(3, &mut chunk) {
            Ok(_) => seen.extend(origins(&chunk)),
            Err(e) => break e,
        }
    };
    // chunks of three lines: the fourth (lines 10–12) holds the error and is not returned
    assert_eq!(seen, (0..8).map(f64::from).collect::<Vec<_>>());
    assert_eq!(err.location, "12");
}

/// A direction of length 1e-320 would put a hit at distance 5 at t = 5e320 = +∞ (a miss):
/// refused on a line and in columns (both paths), while 2⁻⁵¹¹ itself is accepted.
#[test]
fn directions_whose_t_overflows_are_refused() {
    assert_eq!(rays::MIN_DIRECTION, 2f64.powi(-511));
    assert!((5.0 / 1e-320f64).is_infinite());
    let message = rays::ray_from_fields(&[0.0, 0.0, 5.0, 0.0, 0.0, -1e-320], &rays::RaySetup::default()).unwrap_err();
    assert!(
        message.contains("too short") && message.contains("-1e-320"),
        "{message}"
    );
    assert!(rays::ray_from_fields(
        &[0.0, 0.0, 5.0, 0.0, 0.0, -rays::MIN_DIRECTION],
        &rays::RaySetup::default()
    )
    .is_ok());
    let origins = [0.0, 0.0, 5.0, 0.0, 0.0, 5.0];
    let directions = [0.0, 0.0, -1.0, 0.0, 0.0, -1e-320];
    let columns = rays::RayColumns::new(&origins, &directions, &[0.0], &[f64::INFINITY], None).unwrap();
    let (index, message) = columns.rays(&rays::RaySetup::default()).unwrap_err();
    assert_eq!(index, 1);
    assert!(message.contains("too short"), "{message}");
}

#[test]
fn npy_preamble_is_aligned_and_round_trips() {
    let p = npy_preamble(12_345_678_901, NPY_HIT_COLUMNS + 1);
    assert_eq!(p.len(), NPY_PREAMBLE_LEN);
    assert_eq!(p.len() % 64, 0, "NumPy aligns the data to 64 bytes");
    let header = read_npy_header(&mut p.as_slice(), "h").unwrap_err();
    // 12 columns are not a ray array: the header parses, the shape is refused
    assert!(header.message.contains("(12345678901, 12)"), "{header}");
    let rays = npy_preamble(7, 8);
    let h = read_npy_header(&mut rays.as_slice(), "h").unwrap();
    assert_eq!((h.rows, h.columns, h.double), (7, 8, true));
}

/// The header dictionary is parsed as the Python literal it is: any key order, either quote,
/// trailing commas, padding; wrong, missing, repeated or extra keys and trailing text refused.
#[test]
fn npy_header_dictionary_is_parsed_not_searched() {
    let dict = |descr: &str, fortran: bool, shape: &[u64]| HeaderDict {
        descr: descr.into(),
        fortran_order: fortran,
        shape: shape.to_vec(),
    };
    for (text, expected) in [
        (
            "{'descr': '<f8', 'fortran_order': False, 'shape': (3, 6), }       \n",
            dict("<f8", false, &[3, 6]),
        ),
        (
            "{\"shape\":(12,8),\"descr\":\"<f4\",\"fortran_order\":True}",
            dict("<f4", true, &[12, 8]),
        ),
        (
            "{ 'fortran_order' : False , 'shape' : ( 5 , ) , 'descr' : '>f8' }",
            dict(">f8", false, &[5]),
        ),
        (
            "{'descr': '<f8', 'fortran_order': False, 'shape': ()}",
            dict("<f8", false, &[]),
        ),
    ] {
        assert_eq!(parse_header_dict(text).unwrap(), expected, "{text}");
    }
    for (text, message) in [
        // a substring search found 'shape': inside the descr string and read (9, 6)
        (
            "{'descr': \"'shape': (9, 6)\", 'fortran_order': False, 'shape': (2, 6)}",
            None,
        ),
        ("{'descr': '<f8', 'fortran_order': False}", Some("no 'shape'")),
        (
            "{'descr': '<f8', 'fortran_order': False, 'shape': (2, 6), 'shape': (3, 6)}",
            Some("given twice"),
        ),
        (
            "{'descr': '<f8', 'fortran_order': False, 'shape': (2, 6), 'extra': 1}",
            Some("unexpected key 'extra'"),
        ),
        (
            "{'descr': '<f8', 'fortran_order': Falsey, 'shape': (2, 6)}",
            Some("expected True or False"),
        ),
        (
            "{'descr': '<f8', 'fortran_order': False, 'shape': (2, -6)}",
            Some("non-negative integer"),
        ),
        (
            "{'descr': '<f8', 'fortran_order': False, 'shape': (2, 6)} x",
            Some("after the dictionary"),
        ),
        ("'descr': '<f8'", Some("expected `{`")),
    ] {
        match (parse_header_dict(text), message) {
            (Ok(d), None) => assert_eq!(d, dict("'shape': (9, 6)", false, &[2, 6])),
            (Err(e), Some(m)) => assert!(e.contains(m), "{text}: {e}"),
            (other, _) => panic!("{text}: {other:?}"),
        }
    }
    // through the whole preamble: a big-endian dtype is named in the refusal
    let mut bytes = b"\x93NUMPY\x01\x00".to_vec();
    let text = "{'descr': '>f8', 'fortran_order': False, 'shape': (2, 6), }";
    bytes.extend_from_slice(&(text.len() as u16).to_le_bytes());
    bytes.extend_from_slice(text.as_bytes());
    let err = read_npy_header(&mut bytes.as_slice(), "b.npy").unwrap_err();
    assert!(err.message.contains("dtype '>f8' is not supported"), "{err}");
}
