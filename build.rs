//! Build script: lets the binary, the tests and the benches find libtorch at run time without
//! LD_LIBRARY_PATH, through an rpath to the libtorch library directory.
//!
//! `LIBTORCH` comes from `scripts/setup.sh` (the Makefile evaluates it). torch-sys links the
//! libraries; this script only records where they are found when the program starts.

use std::path::PathBuf;

fn main() {
    println!("cargo:rerun-if-env-changed=LIBTORCH");
    println!("cargo:rerun-if-changed=build.rs");
    let Some(libtorch) = std::env::var_os("LIBTORCH") else {
        println!("cargo:warning=LIBTORCH is not set: run `eval \"$(scripts/setup.sh)\"` or use the Makefile");
        return;
    };
    let lib = PathBuf::from(libtorch).join("lib");
    // Applies to every binary, test, bench and example of this package.
    println!("cargo:rustc-link-arg=-Wl,-rpath,{}", lib.display());
}
