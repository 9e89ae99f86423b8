use robotd_vision::markers::{assign_corners, MarkerFinder};
#[test]
fn dev_markers() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/real_images");
    let mut names: Vec<_> = std::fs::read_dir(&dir).unwrap().map(|e| e.unwrap().path()).collect();
    names.sort();
    for p in names {
        if p.extension().is_none_or(|e| e != "jpg") { continue; }
        let img = robotd_vision::still::load(&p).unwrap();
        let mut f = MarkerFinder::new();
        let t = std::time::Instant::now();
        let m = f.find_markers(&img.rgb, img.width, img.height);
        let dt = t.elapsed();
        println!("{} {}x{} {:?}", p.file_name().unwrap().to_string_lossy(), img.width, img.height, dt);
        for k in &m { println!("   {:?}", k); }
        if let Some([o, _]) = assign_corners(&m) { println!("  ORDER {:?}", o.map(|k| k.centre_px)); }
    }
}
