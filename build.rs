//! Build script.
//!
//! 1. libtorch: an rpath to `$LIBTORCH/lib`, so the binary, tests and benches find libtorch at
//!    run time without LD_LIBRARY_PATH (`LIBTORCH` comes from `scripts/setup.sh`; torch-sys
//!    links the libraries).
//! 2. SUMO (feature `sumo`, on by default): compiles `src/sumo/shim.cpp` twice, against libsumo
//!    (prefix `mpg_sumo_`) and against libtraci (prefix `mpg_traci_`), and runs bindgen on
//!    `src/sumo/shim.h` only, once per prefix, with the prefix stripped from the Rust names.
//!    SUMO is found through `SUMO_HOME` (`include/` and `lib/` or `lib64/`, as the
//!    eclipse-sumo wheel lays it out) or else the system paths of Debian's `sumo` package.
//! 3. The bundled configurations and policies (`configs/`, `policies/`): `$OUT_DIR/bundle.rs`
//!    lists them with `include_bytes!`, so that the binary finds them from any folder
//!    (`src/cli/bundled.rs`).

use std::env;
use std::path::PathBuf;

fn main() {
    println!("cargo:rerun-if-env-changed=LIBTORCH");
    println!("cargo:rerun-if-changed=build.rs");
    match env::var_os("LIBTORCH") {
        Some(libtorch) => {
            let lib = PathBuf::from(libtorch).join("lib");
            println!("cargo:rustc-link-arg=-Wl,-rpath,{}", lib.display());
        }
        None => println!(
            "cargo:warning=LIBTORCH is not set: run `eval \"$(scripts/setup.sh)\"` or use the Makefile"
        ),
    }
    #[cfg(feature = "sumo")]
    sumo_shim::build();
    bundle();
}

/// Writes `$OUT_DIR/bundle.rs`: `FILES`, every file under `configs/` and `policies/` as
/// (path relative to the repository, bytes), sorted by path.
fn bundle() {
    let root = PathBuf::from(env::var("CARGO_MANIFEST_DIR").expect("set by cargo"));
    let mut files = Vec::new();
    for dir in ["configs", "policies"] {
        walk(&root.join(dir), &mut files);
    }
    files.sort();
    let mut code = String::from(
        "/// The bundled files: (path relative to the repository, contents).\npub const FILES: &[(&str, &[u8])] = &[\n",
    );
    for file in &files {
        println!("cargo:rerun-if-changed={}", file.display());
        let rel = file.strip_prefix(&root).expect("under the root");
        let rel = rel.to_string_lossy().replace('\\', "/");
        code += &format!(
            "    ({rel:?}, include_bytes!({:?})),\n",
            file.display().to_string()
        );
    }
    code += "];\n";
    let out = PathBuf::from(env::var("OUT_DIR").expect("set by cargo")).join("bundle.rs");
    std::fs::write(out, code).expect("writing bundle.rs");
}

/// Every file under `dir` (and the directories, for cargo to rerun when a file is added).
fn walk(dir: &std::path::Path, files: &mut Vec<PathBuf>) {
    println!("cargo:rerun-if-changed={}", dir.display());
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for entry in entries.flatten() {
        let path = entry.path();
        if path.is_dir() {
            walk(&path, files);
        } else {
            files.push(path);
        }
    }
}

#[cfg(feature = "sumo")]
mod sumo_shim {
    use std::env;
    use std::path::{Path, PathBuf};

    /// Where SUMO's C++ headers and libraries are.
    struct SumoPaths {
        include: PathBuf,
        lib: Option<PathBuf>,
    }

    fn find_sumo() -> SumoPaths {
        println!("cargo:rerun-if-env-changed=SUMO_HOME");
        if let Some(home) = env::var_os("SUMO_HOME").map(PathBuf::from) {
            let include = home.join("include");
            if include.join("libsumo/libsumo.h").is_file() {
                let lib = ["lib", "lib64"]
                    .iter()
                    .map(|d| home.join(d))
                    .find(|d| d.join("libsumocpp.so").is_file());
                return SumoPaths { include, lib };
            }
        }
        let include = PathBuf::from("/usr/include");
        if !include.join("libsumo/libsumo.h").is_file() {
            panic!(
                "SUMO's C++ headers (libsumo/libsumo.h) are neither under $SUMO_HOME/include nor \
             /usr/include: run scripts/setup.sh (Debian package `sumo`), point SUMO_HOME at a \
             SUMO with include/ and lib/, or build with --no-default-features"
            );
        }
        SumoPaths { include, lib: None }
    }

    /// Strips `mpg_sumo_` / `mpg_traci_` from the generated Rust names (the link names keep it).
    #[derive(Debug)]
    struct StripPrefix(&'static str);

    impl bindgen::callbacks::ParseCallbacks for StripPrefix {
        fn generated_name_override(&self, item: bindgen::callbacks::ItemInfo<'_>) -> Option<String> {
            item.name.strip_prefix(self.0).map(str::to_owned)
        }
    }

    pub fn build() {
        let sumo = find_sumo();
        let out = PathBuf::from(env::var("OUT_DIR").expect("OUT_DIR"));
        let shim = Path::new("src/sumo");
        println!("cargo:rerun-if-changed=src/sumo/shim.h");
        println!("cargo:rerun-if-changed=src/sumo/shim.cpp");
        for (prefix, library, traci) in [("mpg_sumo_", "sumocpp", false), ("mpg_traci_", "tracicpp", true)] {
            let mut build = cc::Build::new();
            build
                .cpp(true)
                .std("c++17")
                .file(shim.join("shim.cpp"))
                .include(&sumo.include)
                .include(shim)
                .define("MPG_PREFIX", prefix)
                .warnings(false);
            if traci {
                build.define("LIBTRACI", "1");
            }
            build.compile(&format!("mpg{}", prefix.trim_end_matches('_')));
            if let Some(lib) = &sumo.lib {
                println!("cargo:rustc-link-search=native={}", lib.display());
                println!("cargo:rustc-link-arg=-Wl,-rpath,{}", lib.display());
            }
            println!("cargo:rustc-link-lib=dylib={library}");

            let mut bindings = bindgen::Builder::default()
                .header(shim.join("shim.h").to_string_lossy())
                .clang_arg(format!("-DMPG_PREFIX={prefix}"))
                .allowlist_file(".*shim\\.h")
                .parse_callbacks(Box::new(StripPrefix(prefix)));
            // The structs come once, with the libsumo bindings; the libtraci ones reuse them.
            bindings = if traci {
                bindings.blocklist_type("Mpg.*").blocklist_item("Mpg.*")
            } else {
                bindings
            };
            let name = if traci { "traci.rs" } else { "libsumo.rs" };
            bindings
                .generate()
                .expect("bindgen on src/sumo/shim.h")
                .write_to_file(out.join(name))
                .expect("write the SUMO bindings");
        }
    }
}
