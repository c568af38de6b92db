//! The report's 3D pictures, rendered offscreen by VTK: `python/baffle/render.py` run as
//! a `python3 -c` script (so the baffle package need not be installed, only vtk and
//! numpy), which writes PNGs and `pictures.json` into `--out/pictures`. The report embeds
//! the PNGs; when they cannot be made it says why instead.

use crate::files::read_json;
use serde::Deserialize;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// The renderer, compiled in so the plan finds it wherever the binary is.
const RENDER_SCRIPT: &str = include_str!("../../../../python/baffle/render.py");
/// A renderer that takes longer is stuck (the p2 pictures take about 10 s).
const TIMEOUT: Duration = Duration::from_secs(300);

/// One rendered picture: its PNG bytes and its words.
pub struct Picture {
    pub file: PathBuf,
    pub title: String,
    pub caption: String,
    /// "anatomy" or "flow": the report's section it goes in.
    pub section: String,
    pub png: Vec<u8>,
}

pub enum Pictures {
    Rendered { pictures: Vec<Picture>, notes: Vec<String> },
    /// Why not, in plain words.
    NotRendered(String),
}

/// The folder the pictures go to.
pub fn folder(out: &Path) -> PathBuf {
    out.join("pictures")
}

/// The interpreter that runs the renderer: $BAFFLE_PYTHON, else python3 on PATH.
fn python() -> String {
    std::env::var("BAFFLE_PYTHON").ok().filter(|p| !p.is_empty()).unwrap_or_else(|| "python3".into())
}

/// Render the pictures of the plan in `out` (its report.json and the stages' files
/// written). `frame_ras`: the surfaces are in RAS; `labels`: (name, ModelFaceID) of the parts.
pub fn render(out: &Path, frame_ras: bool, labels: &[(&str, i32)]) -> Pictures {
    render_with(&python(), out, frame_ras, labels)
}

fn render_with(python: &str, out: &Path, frame_ras: bool, labels: &[(&str, i32)]) -> Pictures {
    match run_renderer(python, out, frame_ras, labels).and_then(|()| read_manifest(&folder(out))) {
        Ok(pictures) => pictures,
        Err(reason) => Pictures::NotRendered(reason),
    }
}

fn run_renderer(python: &str, out: &Path, frame_ras: bool, labels: &[(&str, i32)]) -> Result<(), String> {
    let dir = folder(out);
    std::fs::create_dir_all(&dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    // A manifest of an earlier run must not stand in for this one's.
    let _ = std::fs::remove_file(dir.join("pictures.json"));
    let log_path = dir.join("render.log");
    let log = std::fs::File::create(&log_path).map_err(|e| format!("{}: {e}", log_path.display()))?;
    let mut command = Command::new(python);
    command.arg("-c").arg(RENDER_SCRIPT).arg(out).args(["--frame", if frame_ras { "ras" } else { "lps" }]);
    for (name, label) in labels {
        command.arg(format!("--{name}-label")).arg(label.to_string());
    }
    let mut child = command
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(log)
        .spawn()
        .map_err(|e| format!("{python} could not be started ({e}); the pictures need Python 3 with the vtk package (pip install vtk), or set BAFFLE_PYTHON"))?;
    let start = Instant::now();
    let status = loop {
        match child.try_wait() {
            Ok(Some(status)) => break status,
            Ok(None) if start.elapsed() > TIMEOUT => {
                let _ = child.kill();
                let _ = child.wait();
                return Err(format!("the renderer did not finish within {} s (stopped); see {}", TIMEOUT.as_secs(), log_path.display()));
            }
            Ok(None) => std::thread::sleep(Duration::from_millis(100)),
            Err(e) => return Err(format!("waiting for the renderer: {e}")),
        }
    };
    if status.success() {
        return Ok(());
    }
    let text = std::fs::read_to_string(&log_path).unwrap_or_default();
    // The renderer's own message ("baffle.render: ..."), else the log's last line.
    let line = text.lines().rev().find(|l| l.starts_with("baffle.render: ")).or_else(|| text.lines().rev().find(|l| !l.trim().is_empty()));
    let status = status.code().map_or_else(|| "was killed by a signal".to_string(), |c| format!("exited with status {c}"));
    Err(match line {
        Some(line) => format!("{} ({python} {status}; log {})", line.trim_start_matches("baffle.render: "), log_path.display()),
        None => format!("{python} {status} without a message; log {}", log_path.display()),
    })
}

/// pictures.json as the renderer writes it (the fields the report uses).
#[derive(Deserialize)]
struct Manifest {
    pictures: Vec<ManifestEntry>,
    /// What could not be drawn, in words.
    notes: Vec<String>,
}

/// One picture of pictures.json: its PNG file (in the manifest's folder) and its words.
#[derive(Deserialize)]
struct ManifestEntry {
    file: String,
    title: String,
    caption: String,
    section: String,
}

/// The pictures the renderer listed in `dir/pictures.json`, with their PNG bytes.
fn read_manifest(dir: &Path) -> Result<Pictures, String> {
    let path = dir.join("pictures.json");
    let manifest: Manifest = read_json(&path)?;
    let mut pictures = Vec::new();
    for ManifestEntry { file, title, caption, section } in manifest.pictures {
        let file = dir.join(file);
        let png = std::fs::read(&file).map_err(|e| format!("{}: {e}", file.display()))?;
        if !png.starts_with(b"\x89PNG\r\n\x1a\n") {
            return Err(format!("{}: not a PNG", file.display()));
        }
        pictures.push(Picture { file, title, caption, section, png });
    }
    if pictures.is_empty() {
        return Err(format!("{}: lists no picture", path.display()));
    }
    Ok(Pictures::Rendered { pictures, notes: manifest.notes })
}

/// `bytes` as standard base64 (RFC 4648, padded), for a data: URL.
pub fn base64(bytes: &[u8]) -> String {
    const ALPHABET: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut text = String::with_capacity(bytes.len().div_ceil(3) * 4);
    for chunk in bytes.chunks(3) {
        let n = chunk.iter().enumerate().fold(0u32, |n, (k, &b)| n | (u32::from(b) << (16 - 8 * k)));
        for k in 0..4 {
            text.push(if k <= chunk.len() { ALPHABET[(n >> (18 - 6 * k)) as usize & 63] as char } else { '=' });
        }
    }
    text
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn base64_is_rfc_4648() {
        // RFC 4648 section 10's test vectors.
        for (plain, encoded) in [("", ""), ("f", "Zg=="), ("fo", "Zm8="), ("foo", "Zm9v"), ("foob", "Zm9vYg=="), ("fooba", "Zm9vYmE="), ("foobar", "Zm9vYmFy")] {
            assert_eq!(base64(plain.as_bytes()), encoded);
        }
    }

    #[test]
    fn a_manifest_picture_without_its_caption_is_refused_naming_the_file() {
        let dir = std::env::temp_dir().join(format!("baffle-manifest-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        std::fs::write(dir.join("a.png"), b"\x89PNG\r\n\x1a\nrest").unwrap();
        let write = |picture: &str| std::fs::write(dir.join("pictures.json"), format!(r#"{{ "frame": "lps", "pictures": [{picture}], "notes": ["n"] }}"#)).unwrap();
        write(r#"{ "file": "a.png", "title": "t", "caption": "c", "section": "flow", "pixels": {} }"#);
        match read_manifest(&dir) {
            Ok(Pictures::Rendered { pictures, notes }) => assert_eq!((pictures[0].caption.as_str(), pictures[0].section.as_str(), notes), ("c", "flow", vec!["n".to_string()])),
            Ok(Pictures::NotRendered(why)) | Err(why) => panic!("{why}"),
        }
        write(r#"{ "file": "a.png", "title": "t", "section": "flow" }"#);
        let e = read_manifest(&dir).err().unwrap();
        assert!(e.contains("pictures.json") && e.contains("missing field `caption`"), "{e}");
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn a_missing_interpreter_is_named_with_what_the_pictures_need() {
        let dir = std::env::temp_dir().join(format!("baffle-pictures-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        match render_with("/nonexistent/python3", &dir, false, &[]) {
            Pictures::NotRendered(reason) => assert!(reason.contains("/nonexistent/python3") && reason.contains("pip install vtk"), "{reason}"),
            Pictures::Rendered { .. } => panic!("rendered without an interpreter"),
        }
        let _ = std::fs::remove_dir_all(&dir);
    }
}
