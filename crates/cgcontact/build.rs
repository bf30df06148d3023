//! Tells the unit tests which SIMD entry points the build machine can run, so that a test of an
//! instruction set the CPU lacks is reported as *ignored* rather than passing without checking
//! anything (libtest has no run-time skip). The library itself never reads these cfgs: it detects
//! the instruction set at run time.

fn main() {
    println!("cargo::rerun-if-changed=build.rs");
    println!("cargo::rustc-check-cfg=cfg(cgcontact_host_avx2, cgcontact_host_avx512)");
    // Only meaningful when the tests run where they are built.
    let same_machine = std::env::var("HOST").ok() == std::env::var("TARGET").ok();
    #[cfg(target_arch = "x86_64")]
    if same_machine {
        use std::is_x86_feature_detected as has;
        if has!("avx2") {
            println!("cargo::rustc-cfg=cgcontact_host_avx2");
            if has!("avx512f") && has!("avx512vl") {
                println!("cargo::rustc-cfg=cgcontact_host_avx512");
            }
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = same_machine;
}
