//! An append-only line file with a size limit: when the next line would pass `max_bytes`, the
//! file becomes `<path>.1` (older ones shift to `.2` … `.<keep_files>`, the oldest is deleted)
//! and a new one is started. robotd's long-lived line files (the MCP call log, the safety
//! audit) use it, so a service left running for months fills a bounded part of the disk.

use std::fs::{self, File, OpenOptions};
use std::io::{self, BufWriter, Write};
use std::path::{Path, PathBuf};

/// A size-limited line file (see the module).
#[derive(Debug)]
pub struct RotatingFile {
    path: PathBuf,
    max_bytes: u64,
    keep_files: u32,
    out: BufWriter<File>,
    len: u64,
}

/// `<path>.<k>`, the k-th newest rotated file.
pub fn rotated_path(path: &Path, k: u32) -> PathBuf {
    let mut name = path.as_os_str().to_owned();
    name.push(format!(".{k}"));
    PathBuf::from(name)
}

fn open_append(path: &Path) -> io::Result<File> {
    OpenOptions::new().create(true).append(true).open(path)
}

impl RotatingFile {
    /// Opens `path` for appending (creating it), continuing its current size. At most
    /// `keep_files` rotated files are kept (0: none, the full file is deleted).
    pub fn open(path: &Path, max_bytes: u64, keep_files: u32) -> io::Result<Self> {
        let out = BufWriter::new(open_append(path)?);
        let len = out.get_ref().metadata()?.len();
        Ok(Self {
            path: path.to_path_buf(),
            max_bytes,
            keep_files,
            out,
            len,
        })
    }

    /// The file written to.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Writes `bytes` as they are (the caller ends its lines), rotating first when they would
    /// pass the limit. A line larger than the limit gets a file of its own.
    pub fn write(&mut self, bytes: &[u8]) -> io::Result<()> {
        let size = bytes.len() as u64;
        if self.len > 0 && self.len.saturating_add(size) > self.max_bytes {
            self.rotate()?;
        }
        self.out.write_all(bytes)?;
        self.len += size;
        Ok(())
    }

    /// Flushes what was written to the file.
    pub fn flush(&mut self) -> io::Result<()> {
        self.out.flush()
    }

    /// `path.(k)` → `path.(k+1)` for k = keep_files-1 … 1, `path` → `path.1`, new `path`.
    fn rotate(&mut self) -> io::Result<()> {
        self.out.flush()?;
        let (path, keep) = (&self.path, self.keep_files);
        let fail = |p: &Path, e: io::Error| {
            io::Error::new(e.kind(), format!("cannot rotate {}: {e}", p.display()))
        };
        let oldest = rotated_path(path, keep.max(1));
        match fs::remove_file(&oldest) {
            Err(e) if e.kind() != io::ErrorKind::NotFound => return Err(fail(&oldest, e)),
            _ => {}
        }
        for k in (1..keep).rev() {
            let from = rotated_path(path, k);
            if from.exists() {
                fs::rename(&from, rotated_path(path, k + 1)).map_err(|e| fail(&from, e))?;
            }
        }
        let moved = match keep {
            0 => fs::remove_file(path),
            _ => fs::rename(path, rotated_path(path, 1)),
        };
        moved.map_err(|e| fail(path, e))?;
        self.out = BufWriter::new(open_append(path)?);
        self.len = 0;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn old_files_shift_and_the_oldest_goes() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("calls.log");
        let mut file = RotatingFile::open(&path, 10, 2).unwrap();
        for line in ["aaaaaa\n", "bbbbbb\n", "cccccc\n", "dddddd\n"] {
            file.write(line.as_bytes()).unwrap();
        }
        file.flush().unwrap();
        let read = |p: PathBuf| fs::read_to_string(p).unwrap();
        assert_eq!(read(path.clone()), "dddddd\n");
        assert_eq!(read(rotated_path(&path, 1)), "cccccc\n");
        assert_eq!(read(rotated_path(&path, 2)), "bbbbbb\n");
        assert!(!rotated_path(&path, 3).exists());
        // Reopening continues the current file's size.
        let mut again = RotatingFile::open(&path, 10, 2).unwrap();
        again.write(b"ee\n").unwrap();
        again.flush().unwrap();
        assert_eq!(read(path), "dddddd\nee\n");
    }
}
