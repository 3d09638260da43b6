//! Replay a recorded drive through the online localizer, one frame at a time, as a rover's
//! software would call it: print each fix as it happens and the pose once a second.
//!
//! ```sh
//! segloc sim export --seed 3 --session 2 -o drive.jsonl --prior-map session1.map.json
//! cargo run --release --example online_localizer -- drive.jsonl session1.map.json
//! ```
#![warn(clippy::too_many_lines)]

use segloc::localizer::{Localizer, LocalizerConfig, LocalizerEvent};
use segloc::maps::{frames::read_frames, read_map};
use std::path::PathBuf;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1).map(PathBuf::from);
    let (Some(frames_path), prior_path) = (args.next(), args.next()) else {
        eprintln!("usage: online_localizer FRAMES.jsonl [PRIOR.map.json]");
        std::process::exit(2);
    };
    let drive = read_frames(&frames_path)?;
    let prior = prior_path.map(|p| read_map(&p)).transpose()?;
    let config = match &prior {
        Some(map) => LocalizerConfig::default().calibrated_for(map),
        None => LocalizerConfig::default(),
    };
    let mut localizer = Localizer::new(prior, config)?;
    for frame in &drive.frames {
        let out = localizer.push_frame(frame)?;
        for event in &out.events {
            if let LocalizerEvent::Fix {
                frame: k, inliers, ..
            } = event
            {
                println!("{:7.1} s  fix of frame {k} with {inliers} inliers", frame.t);
            }
        }
        if let Some(p) = out.prior_from_rover.filter(|_| out.frame % 10 == 0) {
            let t = p.translation.vector;
            println!(
                "{:7.1} s  prior_from_rover ({:.3}, {:.3}, {:.3})  {:.2} ms",
                frame.t, t.x, t.y, t.z, out.time_ms
            );
        }
    }
    let session = localizer.finish()?;
    let accepted = session.attempts.iter().filter(|a| a.accepted()).count();
    println!(
        "{} frames, {accepted} of {} relocalizations accepted, map of {} boulders",
        drive.frames.len(),
        session.attempts.len(),
        session.map.len()
    );
    Ok(())
}
