//! Writes the figure gallery of docs/figures.md: `cargo run --example gallery` (into
//! docs/figures/, the committed copy) or `cargo run --example gallery -- DIR`.

fn main() -> anyhow::Result<()> {
    let dir = std::env::args()
        .nth(1)
        .map(std::path::PathBuf::from)
        .unwrap_or_else(|| std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("docs/figures"));
    for f in granval::report::gallery::write_all(&dir)? {
        println!("{}", f.display());
    }
    Ok(())
}
