//! A full disk: the audit log lives on a 1 MiB tmpfs that the test fills to the last byte.
//! Motions are then refused with the reason (a motion that cannot be audited does not
//! happen), the tools that only read still answer, `/health` says the disk is low, and robotd
//! keeps serving.
//!
//! Mounting a tmpfs needs root (CI runs as root); elsewhere the test fails saying so, never
//! passes unchecked.

mod common;
#[path = "common/lab.rs"]
mod lab;

use serde_json::json;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::Command;

/// A tmpfs of `size` mounted on a fresh directory; unmounted when dropped.
struct Tmpfs {
    dir: tempfile::TempDir,
}

impl Tmpfs {
    fn mount(size: &str) -> Result<Tmpfs, String> {
        let dir = tempfile::tempdir().map_err(|e| e.to_string())?;
        let out = Command::new("mount")
            .args(["-t", "tmpfs", "-o", &format!("size={size}"), "tmpfs"])
            .arg(dir.path())
            .output()
            .map_err(|e| e.to_string())?;
        if !out.status.success() {
            return Err(String::from_utf8_lossy(&out.stderr).into_owned());
        }
        Ok(Tmpfs { dir })
    }

    fn path(&self) -> &Path {
        self.dir.path()
    }
}

impl Drop for Tmpfs {
    fn drop(&mut self) {
        let _ = Command::new("umount")
            .arg("-l")
            .arg(self.dir.path())
            .status();
    }
}

/// Writes `path` until the file system has no byte left.
fn fill(path: PathBuf) {
    let mut file = std::fs::File::create(path).unwrap();
    let chunk = vec![0u8; 4096];
    loop {
        match file.write(&chunk) {
            Ok(0) => break,
            Ok(_) => {}
            Err(e) => {
                assert_eq!(e.raw_os_error(), Some(libc::ENOSPC), "{e}");
                break;
            }
        }
    }
    // The last partial page: byte by byte.
    while file.write(&[0]).is_ok_and(|n| n == 1) {}
}

#[test]
fn a_full_audit_disk_refuses_motions_with_the_reason_and_reads_still_answer() {
    // SAFETY: geteuid has no preconditions.
    assert!(
        unsafe { libc::geteuid() } == 0,
        "this test mounts a 1 MiB tmpfs to fill it: run the tests as root (CI does), or leave \
         it out with -E 'not test(a_full_audit_disk)'"
    );
    let tmpfs = Tmpfs::mount("1m").unwrap_or_else(|reason| {
        panic!("cannot mount a tmpfs here (the test needs `mount -t tmpfs`): {reason}")
    });
    let audit = tmpfs.path().join("audit.jsonl");
    lab::runtime().block_on(async {
        let lab = lab::lab_with(0.05, &[format!("safety.audit.path={}", audit.display())]).await;
        // Room at first: a motion is audited and runs.
        lab.ok("move2observation_pose", json!({"workspace_id": "niryo_ws"}))
            .await;
        assert!(std::fs::metadata(&audit).unwrap().len() > 0);

        fill(tmpfs.path().join("filler"));
        // The audit file's last page may still take a line or two; then the writer fails.
        let mut refusal = None;
        for _ in 0..20 {
            let (text, _) = lab
                .call("move2observation_pose", json!({"workspace_id": "niryo_ws"}))
                .await;
            if text.contains("audit log writer failed") {
                refusal = Some(text);
                break;
            }
        }
        let refusal = refusal.expect("a motion refused because it cannot be audited");
        assert!(refusal.contains("motion refused"), "{refusal}");

        // Reading still works.
        let (text, _) = lab.call("get_detected_objects", json!({})).await;
        assert!(!text.contains("audit"), "{text}");
        let (text, _) = lab.call("get_system_status", json!({})).await;
        assert!(text.contains("status"), "{text}");

        // /health says where the disk is low.
        let port: u16 = lab.url.rsplit(':').next().unwrap().parse().unwrap();
        // A degraded service answers /health with 503 (and the report).
        let (status, body) = common::http_get(port, "/health");
        assert_eq!(status, 503, "{body}");
        let health: serde_json::Value = serde_json::from_str(&body).unwrap();
        assert_eq!(health["status"], "degraded", "{body}");
        assert_eq!(health["disk"]["low"], true, "{body}");
        let reason = health["disk"]["reason"].as_str().unwrap();
        assert!(
            reason.contains(&format!("audit {}", tmpfs.path().display())),
            "{reason}"
        );
    });
}
