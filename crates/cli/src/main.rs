//! The `servo` command-line tool.

fn main() {
    println!("servo {}", env!("CARGO_PKG_VERSION"));
}
