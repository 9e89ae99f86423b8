use robotd_vision::markers::MarkerFinder;
fn main() {
    let path = std::env::args().nth(1).unwrap();
    let img = robotd_vision::still::load(std::path::Path::new(&path)).unwrap();
    let mut f = MarkerFinder::new();
    let m = f.find_markers(&img.rgb, img.width, img.height);
    for x in &m {
        println!("{x:?}");
    }
}
