//! The GPU kernels' SPIR-V module, for `include_bytes!(env!("kernel.spv"))`.
//!
//! `kernel/compiled/` holds the module compiled from `kernel/` and `shared/` together with a
//! fingerprint of everything that compilation reads (sources, manifests, the locked versions of
//! the kernel's dependencies, the toolchain, the compiler's settings). When the fingerprint
//! matches, the build takes that module and never builds the shader compiler, which alone
//! takes most of half an hour on two cores. When the sources changed, the build runs
//! `kernel/compiler` (rust-gpu) and refreshes `kernel/compiled/`, so that a change to the
//! kernels and its module are committed together, as Cargo.lock is with a manifest.
//!
//! `GRIDRT_KERNEL_MODULE=committed` makes a stale module an error instead of a compilation
//! (CI: a commit that forgot its module fails at once); `=compile` compiles even when the
//! module is current.

#[cfg(feature = "gpu")]
mod kernel_module {
    use sha2::{Digest, Sha256};
    use std::collections::BTreeSet;
    use std::env;
    use std::error::Error;
    use std::fs;
    use std::path::{Path, PathBuf};
    use std::process::Command;

    type Result<T> = std::result::Result<T, Box<dyn Error>>;

    const MODE: &str = "GRIDRT_KERNEL_MODULE";

    /// Prints the `kernel.spv` path for the host, compiling the module first when it is stale.
    pub fn provide() -> Result<()> {
        let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
        let compiled = root.join("kernel/compiled");
        let inputs = inputs(&root)?;
        for input in &inputs {
            println!("cargo:rerun-if-changed={}", input.display());
        }
        println!("cargo:rerun-if-changed={}", root.join("Cargo.toml").display());
        println!("cargo:rerun-if-changed={}", root.join("Cargo.lock").display());
        println!("cargo:rerun-if-env-changed={MODE}");
        let fingerprint = fingerprint(&root, &inputs)?;
        let recorded = fs::read_to_string(compiled.join("fingerprint")).unwrap_or_default();
        let mode = env::var(MODE).unwrap_or_default();
        let current = recorded.trim() == fingerprint && compiled.join("kernel.spv").is_file();
        let module = match (current, mode.as_str()) {
            (true, "compile") | (false, "") | (false, "compile") => compile(&root, &compiled, &fingerprint)?,
            (true, _) => compiled.join("kernel.spv"),
            (false, _) => {
                return Err(format!(
                    "kernel/compiled/kernel.spv does not match kernel/ and shared/ ({MODE}={mode}): \
                     build once without {MODE} to compile it, and commit kernel/compiled/"
                )
                .into())
            }
        };
        println!("cargo:rustc-env=kernel.spv={}", module.display());
        Ok(())
    }

    /// The files the kernel's compilation reads from this repository, in a fixed order.
    fn inputs(root: &Path) -> Result<Vec<PathBuf>> {
        let mut files = BTreeSet::new();
        for file in [
            "rust-toolchain.toml",
            "shared/Cargo.toml",
            "kernel/Cargo.toml",
            "kernel/compiler/Cargo.toml",
            "kernel/compiler/Cargo.lock",
        ] {
            files.insert(root.join(file));
        }
        for dir in ["shared/src", "kernel/src", "kernel/compiler/src"] {
            walk(&root.join(dir), &mut files)?;
        }
        Ok(files.into_iter().collect())
    }

    fn walk(dir: &Path, files: &mut BTreeSet<PathBuf>) -> Result<()> {
        for entry in fs::read_dir(dir).map_err(|e| format!("{}: {e}", dir.display()))? {
            let path = entry?.path();
            if path.is_dir() {
                walk(&path, files)?;
            } else {
                files.insert(path);
            }
        }
        Ok(())
    }

    /// SHA-256 over the inputs' paths and text (line endings normalised, so that a checkout
    /// with CRLF endings matches), the root manifest's workspace-wide settings and profiles,
    /// and the locked packages the kernel depends on.
    fn fingerprint(root: &Path, inputs: &[PathBuf]) -> Result<String> {
        let mut hash = Sha256::new();
        for input in inputs {
            let relative = input.strip_prefix(root)?.to_string_lossy().replace('\\', "/");
            let bytes = fs::read(input).map_err(|e| format!("{}: {e}", input.display()))?;
            let text: Vec<u8> = bytes.into_iter().filter(|&b| b != b'\r').collect();
            hash.update(format!("{relative}\n{}\n", text.len()));
            hash.update(text);
        }
        let manifest: toml::Table = fs::read_to_string(root.join("Cargo.toml"))?.parse()?;
        for path in [&["profile"][..], &["workspace", "package"], &["workspace", "lints"]] {
            let value = path
                .iter()
                .try_fold(&manifest, |table, key| table.get(*key)?.as_table());
            hash.update(format!(
                "{}={}\n",
                path.join("."),
                value.map(|v| v.to_string()).unwrap_or_default()
            ));
        }
        for package in kernel_packages(&fs::read_to_string(root.join("Cargo.lock"))?)? {
            hash.update(format!("{package}\n"));
        }
        Ok(hash.finalize().iter().map(|b| format!("{b:02x}")).collect())
    }

    /// "name version source checksum" of every package in Cargo.lock that the `kernel` crate
    /// reaches through its dependencies, sorted.
    fn kernel_packages(lock: &str) -> Result<Vec<String>> {
        let lock: toml::Table = lock.parse()?;
        let packages = lock
            .get("package")
            .and_then(|p| p.as_array())
            .ok_or("Cargo.lock without packages")?;
        let text = |p: &toml::Value, key: &str| p.get(key).and_then(|v| v.as_str()).unwrap_or("").to_string();
        let mut reached = BTreeSet::new();
        let mut pending = vec!["kernel".to_string()];
        while let Some(wanted) = pending.pop() {
            // A dependency is written "name" or, when several versions are locked, "name version".
            let mut parts = wanted.splitn(2, ' ');
            let (name, version) = (parts.next().unwrap_or(""), parts.next());
            for package in packages {
                if text(package, "name") != name || version.is_some_and(|v| text(package, "version") != v) {
                    continue;
                }
                let id = format!(
                    "{} {} {} {}",
                    name,
                    text(package, "version"),
                    text(package, "source"),
                    text(package, "checksum")
                );
                if reached.insert(id) {
                    for dependency in package
                        .get("dependencies")
                        .and_then(|d| d.as_array())
                        .into_iter()
                        .flatten()
                    {
                        if let Some(dependency) = dependency.as_str() {
                            // "name version (source)": the source adds nothing the id lacks.
                            pending.push(dependency.split(" (").next().unwrap_or(dependency).to_string());
                        }
                    }
                }
            }
        }
        Ok(reached.into_iter().collect())
    }

    /// Runs kernel/compiler into this build's output folder and refreshes kernel/compiled/.
    fn compile(root: &Path, compiled: &Path, fingerprint: &str) -> Result<PathBuf> {
        let out_dir = PathBuf::from(env::var("OUT_DIR")?);
        let module = out_dir.join("kernel.spv");
        // Its own target folder beside this build's (this one is locked while we run).
        let target = out_dir.ancestors().nth(4).unwrap_or(&out_dir).join("kernel-compiler");
        let cargo = env::var("CARGO").unwrap_or_else(|_| "cargo".into());
        let mut command = Command::new(cargo);
        command
            .current_dir(root.join("kernel/compiler"))
            .args(["run", "--release", "--locked", "--quiet", "--"])
            .arg(&module)
            .env("CARGO_TARGET_DIR", &target);
        for inherited in [
            "RUSTC",
            "RUSTC_WRAPPER",
            "RUSTC_WORKSPACE_WRAPPER",
            "RUSTFLAGS",
            "CARGO_ENCODED_RUSTFLAGS",
            "CARGO_BUILD_TARGET",
        ] {
            command.env_remove(inherited);
        }
        let status = command
            .status()
            .map_err(|e| format!("running the kernel compiler: {e}"))?;
        if !status.success() {
            return Err("compiling the GPU kernels (kernel/compiler) failed: see the errors above".into());
        }
        // The module first, its fingerprint last: an interrupted refresh reads as stale.
        let refreshed = fs::create_dir_all(compiled)
            .and_then(|_| fs::copy(&module, compiled.join("kernel.spv")))
            .and_then(|_| fs::write(compiled.join("fingerprint"), format!("{fingerprint}\n")));
        match refreshed {
            Ok(()) => println!(
                "cargo:warning=GPU kernels compiled from changed sources: kernel/compiled/ refreshed, commit it with them"
            ),
            Err(e) => println!("cargo:warning=GPU kernels compiled, but kernel/compiled/ could not be refreshed: {e}"),
        }
        Ok(module)
    }
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    #[cfg(feature = "gpu")]
    kernel_module::provide()?;
    Ok(())
}
