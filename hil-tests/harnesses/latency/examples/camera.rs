//! The camera-frame rows of `grop latency` alone (iceoryx2 written in place, grop-ipc's
//! `publish_with` and `publish_frame`, Unix socket, TCP; polling and sleeping subscribers):
//! `cargo run --release -p latency --example camera -- [ROUNDS] [--no-build]`. Prints the
//! markdown section. `--no-build`: use the `grop-latency-peer` already built beside it (built
//! with the same profile and settings as this example).

fn main() -> anyhow::Result<()> {
    let mut rounds = 10;
    let mut build = true;
    for arg in std::env::args().skip(1) {
        if arg == "--no-build" {
            build = false;
        } else {
            rounds = arg
                .parse::<usize>()
                .map_err(|e| anyhow::anyhow!("rounds {arg:?}: {e}"))?;
        }
    }
    let peer = latency::peer::locate(build)?;
    let config = latency::camera::CameraConfig {
        rounds,
        ..latency::camera::CameraConfig::default()
    };
    let result = latency::camera::measure(&peer, &config)?;
    println!("{}", latency::report::camera_markdown(&result));
    Ok(())
}
