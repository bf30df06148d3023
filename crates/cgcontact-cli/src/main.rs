//! The `cgcontact` command line (filled by issue 4).
fn main() {
    eprintln!("cgcontact: the command line is not built yet");
    std::process::exit(2);
}
