//! Writing a command's outputs.

use anyhow::{Context, Result};
use std::path::{Path, PathBuf};

/// Write each file through a temporary sibling and rename, so that a failure part-way leaves
/// no half-written program behind.
pub(crate) fn write_all(files: &[(Option<&Path>, &String)]) -> Result<()> {
    let mut staged = Vec::new();
    for (path, text) in files {
        let Some(path) = path else { continue };
        let mut tmp = path.as_os_str().to_owned();
        tmp.push(".whirl-tmp");
        let tmp = PathBuf::from(tmp);
        if let Err(e) = std::fs::write(&tmp, text) {
            let _ = std::fs::remove_file(&tmp);
            for (t, _) in &staged {
                let _ = std::fs::remove_file(t);
            }
            return Err(e).with_context(|| format!("cannot write {}", path.display()));
        }
        staged.push((tmp, path.to_path_buf()));
    }
    for (tmp, path) in staged {
        std::fs::rename(&tmp, &path).with_context(|| format!("cannot write {}", path.display()))?;
    }
    Ok(())
}
