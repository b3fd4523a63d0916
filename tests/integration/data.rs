//! Sample data by name: the data directory holds every sample with the manifest's
//! checksums; `vwb data fetch` against a local HTTP server (an interrupted download
//! resumes with a Range request, a corrupt one is refused and deleted), from a folder
//! and from the embedded voxels; a hidden data directory gives the fetch command.

use std::collections::HashMap;
use std::io::{BufRead, BufReader, Write};
use std::net::TcpListener;
use std::path::PathBuf;
use std::process::Command;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use vwb_app::data_cmd::{self, Source};
use vwb_render::samples::{self, FileState};

use crate::common::*;

#[test]
fn every_sample_in_the_data_directory_matches_the_manifest() {
    let dir = data_dir();
    for s in &samples::manifest().samples {
        for f in &s.files {
            assert_eq!(
                samples::check_file(&dir, f, true).unwrap(),
                FileState::Verified,
                "{}: {} in {}",
                s.name,
                f.name,
                dir.display()
            );
        }
        let header = samples::resolve(&s.name).unwrap();
        vwb_render::volume::load(&header).unwrap_or_else(|e| panic!("{}: {e}", s.name));
    }
}

/// What the local server does with the next request for a file.
#[derive(Default)]
struct Plan {
    /// Send the full Content-Length but only this many body bytes of that file, once.
    cut: Option<(String, usize)>,
    /// Flip a byte of this file in every response.
    corrupt: Option<String>,
    /// Request lines and Range headers seen.
    seen: Vec<(String, Option<String>)>,
}

/// A bounded HTTP/1.1 file server on 127.0.0.1 (Range support, `Connection: close`)
/// that stops after 30 s or 32 connections.
fn serve(files: HashMap<String, Vec<u8>>, plan: Arc<Mutex<Plan>>) -> String {
    let listener = TcpListener::bind("127.0.0.1:0").unwrap();
    let url = format!("http://{}", listener.local_addr().unwrap());
    listener.set_nonblocking(true).unwrap();
    std::thread::spawn(move || {
        let deadline = Instant::now() + Duration::from_secs(30);
        let mut served = 0;
        while Instant::now() < deadline && served < 32 {
            let Ok((mut stream, _)) = listener.accept() else {
                std::thread::sleep(Duration::from_millis(5));
                continue;
            };
            served += 1;
            stream.set_nonblocking(false).unwrap();
            stream
                .set_read_timeout(Some(Duration::from_secs(5)))
                .unwrap();
            let mut reader = BufReader::new(stream.try_clone().unwrap());
            let mut first = String::new();
            reader.read_line(&mut first).unwrap();
            let mut range = None;
            loop {
                let mut line = String::new();
                if reader.read_line(&mut line).unwrap_or(0) == 0 || line.trim().is_empty() {
                    break;
                }
                if let Some((k, v)) = line.split_once(':')
                    && k.eq_ignore_ascii_case("range")
                {
                    range = Some(v.trim().to_string());
                }
            }
            let name = first
                .split_whitespace()
                .nth(1)
                .unwrap_or("/")
                .trim_start_matches('/')
                .to_string();
            let mut plan = plan.lock().unwrap();
            plan.seen.push((name.clone(), range.clone()));
            let Some(mut body) = files.get(&name).cloned() else {
                let _ = stream.write_all(
                    b"HTTP/1.1 404 Not Found\r\nContent-Length: 0\r\nConnection: close\r\n\r\n",
                );
                continue;
            };
            if plan.corrupt.as_deref() == Some(name.as_str()) {
                let mid = body.len() / 2;
                body[mid] ^= 0xff;
            }
            let total = body.len();
            let start = range
                .as_deref()
                .and_then(|r| r.strip_prefix("bytes="))
                .and_then(|r| r.strip_suffix('-'))
                .and_then(|n| n.parse::<usize>().ok())
                .filter(|&n| n < total);
            let head = match start {
                Some(s) => format!(
                    "HTTP/1.1 206 Partial Content\r\nContent-Range: bytes {s}-{}/{total}\r\nContent-Length: {}\r\nConnection: close\r\n\r\n",
                    total - 1,
                    total - s
                ),
                None => format!(
                    "HTTP/1.1 200 OK\r\nContent-Length: {total}\r\nConnection: close\r\n\r\n"
                ),
            };
            let mut body = &body[start.unwrap_or(0)..];
            if let Some((file, n)) = plan.cut.take() {
                if file == name {
                    body = &body[..n];
                } else {
                    plan.cut = Some((file, n));
                }
            }
            let _ = stream.write_all(head.as_bytes());
            let _ = stream.write_all(body);
            let _ = stream.flush();
        }
    });
    url
}

fn storm_files() -> HashMap<String, Vec<u8>> {
    let dir = data_dir();
    let s = samples::manifest().get("storm_wind").unwrap();
    s.files
        .iter()
        .map(|f| (f.name.clone(), std::fs::read(dir.join(&f.name)).unwrap()))
        .collect()
}

fn fresh_dir(name: &str) -> PathBuf {
    let d = tmp(name);
    let _ = std::fs::remove_dir_all(&d);
    d
}

#[test]
fn fetch_over_http_resumes_an_interrupted_download() {
    let s = samples::manifest().get("storm_wind").unwrap();
    let raw = &s.files[1].name;
    let plan = Arc::new(Mutex::new(Plan {
        cut: Some((raw.clone(), 10_000)),
        ..Default::default()
    }));
    let url = serve(storm_files(), plan.clone());
    let dir = fresh_dir("fetch-resume");
    let source = Source::parse(&url);
    let names = ["storm_wind".to_string()];
    // the connection drops after 10 000 bytes: an error, the .part keeps them
    let first = data_cmd::fetch(&names, &dir, Some(&source)).unwrap();
    let e = first[0].as_ref().unwrap_err();
    assert!(e.contains("resumes"), "{e}");
    let part = dir.join(format!("{raw}.part"));
    assert_eq!(std::fs::metadata(&part).unwrap().len(), 10_000);
    assert!(!dir.join(raw).exists());
    // the header arrived whole and verified
    assert_eq!(
        samples::check_file(&dir, s.header(), true).unwrap(),
        FileState::Verified
    );
    // the same command resumes with a Range request and verifies
    let second = data_cmd::fetch(&names, &dir, Some(&source)).unwrap();
    assert!(second[0].is_ok(), "{:?}", second[0]);
    assert!(!part.exists());
    for f in &s.files {
        assert_eq!(
            samples::check_file(&dir, f, true).unwrap(),
            FileState::Verified
        );
    }
    let seen = plan.lock().unwrap().seen.clone();
    assert!(
        seen.contains(&(raw.clone(), Some("bytes=10000-".into()))),
        "{seen:?}"
    );
    // the header was not fetched twice
    assert_eq!(
        seen.iter().filter(|(n, _)| n == &s.header().name).count(),
        1
    );
    // a verified sample is kept: no request at all
    let n = seen.len();
    assert!(data_cmd::fetch(&names, &dir, Some(&source)).unwrap()[0].is_ok());
    assert_eq!(plan.lock().unwrap().seen.len(), n);
}

#[test]
fn fetch_refuses_and_deletes_a_corrupt_download() {
    let s = samples::manifest().get("storm_wind").unwrap();
    let raw = &s.files[1].name;
    let plan = Arc::new(Mutex::new(Plan {
        corrupt: Some(raw.clone()),
        ..Default::default()
    }));
    let url = serve(storm_files(), plan.clone());
    let dir = fresh_dir("fetch-corrupt");
    let out = data_cmd::fetch(&["storm_wind".into()], &dir, Some(&Source::parse(&url))).unwrap();
    let e = out[0].as_ref().unwrap_err();
    assert!(
        e.contains("does not match") && e.contains("refused and deleted"),
        "{e}"
    );
    assert!(!dir.join(raw).exists());
    assert!(!dir.join(format!("{raw}.part")).exists());
    // a missing file on the server is an error naming the URL
    plan.lock().unwrap().corrupt = None;
    let e = data_cmd::download(&format!("{url}/nope.raw"), &dir.join("nope.part"), 10).unwrap_err();
    let e = format!("{e:#}");
    assert!(e.contains("nope.raw") && e.contains("404"), "{e}");
}

fn vwb(data_dir: &std::path::Path) -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_vwb"));
    c.current_dir(repo())
        .env("VWB_DATA_DIR", data_dir)
        .env_remove("VWB_DATA_URL");
    c
}

/// With the data directory empty, a preset that names a sample fails with the command
/// that fetches it; `vwb data list` says what is missing; `vwb data fetch` fills it from
/// the embedded voxels (mri_head) or a folder mirror, and refuses without a source.
#[test]
fn a_hidden_data_directory_names_the_fetch_command() {
    let dir = fresh_dir("empty-data");
    std::fs::create_dir_all(&dir).unwrap();
    let png = tmp("hidden.png");
    let o = vwb(&dir)
        .args(["render", "--preset", "presets/ct_head.ron", "-o"])
        .arg(&png)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("run `vwb data fetch ct_head`"), "{stderr}");
    assert!(stderr.contains(&dir.display().to_string()), "{stderr}");

    let o = vwb(&dir).args(["data", "list"]).output().unwrap();
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success());
    assert!(
        stdout.contains("missing (vwb data fetch nuclei)"),
        "{stdout}"
    );

    // no source for a converted sample: an honest refusal naming --from
    let o = vwb(&dir)
        .args(["data", "fetch", "ct_head"])
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("--from URL_OR_DIR ct_head"), "{stderr}");

    // mri_head from the binary, storm_wind from a folder mirror
    let o = vwb(&dir)
        .args(["data", "fetch", "mri_head"])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let o = vwb(&dir)
        .args(["data", "fetch", "storm_wind", "--from"])
        .arg(data_dir())
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let o = vwb(&dir).args(["data", "list"]).output().unwrap();
    let stdout = String::from_utf8_lossy(&o.stdout);
    for name in ["mri_head", "storm_wind"] {
        let line = stdout.lines().find(|l| l.starts_with(name)).unwrap();
        assert!(line.ends_with("verified"), "{line}");
    }
    // and the MRI preset renders from it
    let o = vwb(&dir)
        .args([
            "render",
            "--preset",
            "presets/mri_head.ron",
            "--size",
            "32x32",
            "-o",
        ])
        .arg(&png)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}
