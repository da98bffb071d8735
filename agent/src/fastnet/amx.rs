//! Intel AMX: detection, and the tile kernel of `bf16_matmul` (`tdpbf16ps`, bf16 products with
//! f32 accumulation). Stable Rust has no AMX intrinsics, so the kernel is `asm!` with the tiles
//! named literally (tmm0–3 accumulate a 32 × 32 block of the output, tmm4–5 hold two 16-row strips
//! of the left matrix, tmm6–7 two 16-column strips of the right one). The layouts and the bounds
//! checks that make it safe to call are `bf16_matmul`'s.

#![allow(unsafe_code)]

use std::sync::OnceLock;

use super::bf16_layout::{AView, PackedB};
use super::gemm::View;

/// Rows (and columns) of one accumulator tile.
const TILE: usize = 16;

/// Whether this process may run the AMX kernel: `Ok` on a CPU with AMX-TILE and AMX-BF16 whose
/// OS enables and grants the tile state, else the reason it may not (for the log line that says
/// which path runs). Checked once per process.
pub fn available() -> Result<(), &'static str> {
    static STATE: OnceLock<Result<(), &'static str>> = OnceLock::new();
    *STATE.get_or_init(detect)
}

#[cfg(target_arch = "x86_64")]
fn detect() -> Result<(), &'static str> {
    use std::arch::asm;
    use std::arch::x86_64::__cpuid_count;
    #[allow(unused_unsafe)]
    // SAFETY: CPUID exists on every x86_64 CPU.
    let (leaf1, leaf7) = unsafe { (__cpuid_count(1, 0), __cpuid_count(7, 0)) };
    if leaf7.edx & (1 << 24) == 0 {
        return Err("the CPU has no AMX-TILE (CPUID leaf 7 EDX bit 24)");
    }
    if leaf7.edx & (1 << 22) == 0 {
        return Err("the CPU has no AMX-BF16 (CPUID leaf 7 EDX bit 22)");
    }
    if leaf1.ecx & (1 << 27) == 0 {
        return Err("the OS has not enabled XSAVE (CPUID leaf 1 ECX bit 27)");
    }
    let (lo, _hi): (u32, u32);
    // SAFETY: XGETBV is available once OSXSAVE is set (checked above); it reads XCR0 only.
    unsafe { asm!("xgetbv", in("ecx") 0u32, out("eax") lo, out("edx") _hi, options(nomem, nostack, preserves_flags)) };
    if lo & (0b11 << 17) != 0b11 << 17 {
        return Err("the OS does not enable the tile state (XCR0 bits 17-18)");
    }
    // Linux hands out the 8 KiB tile state only on request: arch_prctl(ARCH_REQ_XCOMP_PERM,
    // XFEATURE_XTILEDATA), once per process; without it the first tile instruction is a SIGILL.
    const SYS_ARCH_PRCTL: i64 = 158;
    const ARCH_REQ_XCOMP_PERM: i64 = 0x1023;
    const XFEATURE_XTILEDATA: i64 = 18;
    let ret: i64;
    // SAFETY: a plain Linux system call that changes no memory of ours; rcx and r11 are clobbered
    // by `syscall` and declared so.
    unsafe {
        asm!(
            "syscall",
            inlateout("rax") SYS_ARCH_PRCTL => ret,
            in("rdi") ARCH_REQ_XCOMP_PERM,
            in("rsi") XFEATURE_XTILEDATA,
            lateout("rcx") _,
            lateout("r11") _,
            options(nostack)
        );
    }
    if ret != 0 {
        return Err("the kernel refused the tile state (arch_prctl ARCH_REQ_XCOMP_PERM)");
    }
    Ok(())
}

#[cfg(not(target_arch = "x86_64"))]
fn detect() -> Result<(), &'static str> {
    Err("AMX exists only on x86_64")
}

/// `dst = a · b` (or `+=`) on the tiles, on the calling thread.
///
/// # Safety
/// AMX is [`available`], and `bf16_matmul::matmul` has checked the views against their slices
/// and the shapes against each other, with at least one row, one column and one K step.
pub(super) unsafe fn matmul_unchecked(dst: &mut [f32], d: View, accumulate: bool, a: &[u16], av: AView, b: &PackedB) {
    let mut config = TileConfig::default();
    let mut loaded = None;
    // K in passes of at most K_BLOCK steps, each swept over the whole output: a pass's B panel
    // (K_BLOCK·32 × N bf16: 24 KiB for N = 64) and one row strip pair of A (12 KiB) stay in L1
    // while the output's tiles are loaded and stored around them.
    for kb in av.k_blocks(b.n_pad) {
        let (a_k, b_k, chunks) = (kb.a_k, kb.b_k, kb.chunks);
        let acc = accumulate || !kb.first;
        for i0 in (0..d.rows).step_by(2 * TILE) {
            let mr0 = (d.rows - i0).min(TILE);
            let mr1 = (d.rows - i0 - mr0).min(TILE);
            for j0 in (0..d.cols).step_by(2 * TILE) {
                let nr0 = (d.cols - j0).min(TILE);
                let nr1 = (d.cols - j0 - nr0).min(TILE);
                let shape = (mr0, mr1, nr0, nr1);
                if loaded != Some(shape) {
                    config.set(shape);
                    // SAFETY: AMX is available (the caller's contract); the configuration is
                    // well-formed (palette 1, at most 16 rows and 64 bytes per tile).
                    unsafe { load_config(&config) };
                    loaded = Some(shape);
                }
                let block = Block {
                    // The second strips repeat the first where the block has only one:
                    // their results are then computed and dropped, and nothing outside the
                    // views is read.
                    a0: a_k + i0 * av.row_stride,
                    a1: a_k + (i0 + if mr1 > 0 { TILE } else { 0 }) * av.row_stride,
                    b0: b_k + j0 * 2,
                    b1: b_k + (j0 + if nr1 > 0 { TILE } else { 0 }) * 2,
                    c: d.offset + i0 * d.row_stride + j0,
                    c_second_rows: d.offset + (i0 + TILE) * d.row_stride + j0,
                    tiles: (mr1 > 0, nr1 > 0),
                };
                // SAFETY: every tile row the kernel reads lies inside the views the caller
                // checked: A rows i0..i0 + mr (< av.rows), this block's K steps of one
                // segment; B's rows of those K steps, columns j0..j0 + nr (< n_pad); C rows
                // and columns inside `d`. Tiles are configured to those sizes.
                unsafe { block.run(dst, d.row_stride, acc, a, av.row_stride, chunks, b) };
            }
        }
    }
    // SAFETY: AMX is available; releasing the tiles only drops their state.
    unsafe { release() };
}

/// A tile configuration (palette 1): per tile, rows and bytes per row.
#[repr(C, align(64))]
#[derive(Debug, Clone, Copy)]
struct TileConfig([u8; 64]);

impl Default for TileConfig {
    fn default() -> Self {
        let mut c = [0u8; 64];
        c[0] = 1;
        Self(c)
    }
}

impl TileConfig {
    /// Tiles for a block of `mr0 + mr1` rows and `nr0 + nr1` columns (a zero repeats the first).
    fn set(&mut self, (mr0, mr1, nr0, nr1): (usize, usize, usize, usize)) {
        let (mr1, nr1) = (if mr1 == 0 { mr0 } else { mr1 }, if nr1 == 0 { nr0 } else { nr1 });
        // tmm0..3: C (rows × 4·cols bytes); tmm4..5: A strips (rows × 64 bytes); tmm6..7: B strips
        // (16 pair-rows × 4·cols bytes).
        let tiles = [(mr0, 4 * nr0), (mr0, 4 * nr1), (mr1, 4 * nr0), (mr1, 4 * nr1), (mr0, 64), (mr1, 64), (16, 4 * nr0), (16, 4 * nr1)];
        for (t, (rows, bytes)) in tiles.into_iter().enumerate() {
            let bytes = u16::try_from(bytes).expect("tile row of at most 64 bytes");
            self.0[16 + 2 * t..18 + 2 * t].copy_from_slice(&bytes.to_le_bytes());
            self.0[48 + t] = u8::try_from(rows).expect("tile of at most 16 rows");
        }
    }
}

/// One 32 × 32 (or smaller) block of the output: element offsets of its strips.
struct Block {
    a0: usize,
    a1: usize,
    b0: usize,
    b1: usize,
    c: usize,
    c_second_rows: usize,
    /// Whether the block has second row and column strips.
    tiles: (bool, bool),
}

#[cfg(target_arch = "x86_64")]
unsafe fn load_config(config: &TileConfig) {
    // SAFETY: the caller checked AMX; `config` is 64 aligned bytes.
    unsafe { std::arch::asm!("ldtilecfg [{}]", in(reg) config.0.as_ptr(), options(nostack, readonly)) };
}

#[cfg(target_arch = "x86_64")]
unsafe fn release() {
    // SAFETY: the caller checked AMX.
    unsafe { std::arch::asm!("tilerelease", options(nostack, nomem)) };
}

impl Block {
    /// Runs the block's K loop. The tiles persist between the three `asm!` blocks (no code the
    /// compiler emits touches them).
    #[cfg(target_arch = "x86_64")]
    #[allow(clippy::too_many_arguments)]
    unsafe fn run(&self, dst: &mut [f32], ldc: usize, accumulate: bool, a: &[u16], a_row_stride: usize, chunks: usize, b: &PackedB) {
        use std::arch::asm;
        let ldc_bytes = ldc * 4;
        let c0 = dst.as_mut_ptr().wrapping_add(self.c);
        let c1 = dst.as_mut_ptr().wrapping_add(self.c_second_rows);
        let (rows2, cols2) = self.tiles;
        // SAFETY (all blocks): the caller checked every address against the views and configured
        // the tiles to the block's size.
        unsafe {
            if accumulate {
                asm!("tileloadd tmm0, [{c} + {ldc}*1]", c = in(reg) c0, ldc = in(reg) ldc_bytes, options(nostack, readonly));
                if cols2 {
                    asm!("tileloadd tmm1, [{c} + {ldc}*1 + 64]", c = in(reg) c0, ldc = in(reg) ldc_bytes, options(nostack, readonly));
                } else {
                    asm!("tilezero tmm1", options(nostack, nomem));
                }
                if rows2 {
                    asm!("tileloadd tmm2, [{c} + {ldc}*1]", c = in(reg) c1, ldc = in(reg) ldc_bytes, options(nostack, readonly));
                } else {
                    asm!("tilezero tmm2", options(nostack, nomem));
                }
                if rows2 && cols2 {
                    asm!("tileloadd tmm3, [{c} + {ldc}*1 + 64]", c = in(reg) c1, ldc = in(reg) ldc_bytes, options(nostack, readonly));
                } else {
                    asm!("tilezero tmm3", options(nostack, nomem));
                }
            } else {
                asm!("tilezero tmm0", "tilezero tmm1", "tilezero tmm2", "tilezero tmm3", options(nostack, nomem));
            }
            let lda = a_row_stride * 2;
            let ldb = b.n_pad * 4;
            asm!(
                "2:",
                "tileloadd tmm4, [{a0} + {lda}*1]",
                "tileloadd tmm6, [{b0} + {ldb}*1]",
                "tileloadd tmm7, [{b1} + {ldb}*1]",
                "tdpbf16ps tmm0, tmm4, tmm6",
                "tdpbf16ps tmm1, tmm4, tmm7",
                "tileloadd tmm5, [{a1} + {lda}*1]",
                "tdpbf16ps tmm2, tmm5, tmm6",
                "tdpbf16ps tmm3, tmm5, tmm7",
                "add {a0}, 64",
                "add {a1}, 64",
                "add {b0}, {bstep}",
                "add {b1}, {bstep}",
                "dec {kk}",
                "jnz 2b",
                a0 = inout(reg) a.as_ptr().wrapping_add(self.a0) => _,
                a1 = inout(reg) a.as_ptr().wrapping_add(self.a1) => _,
                b0 = inout(reg) b.data.as_ptr().wrapping_add(self.b0) => _,
                b1 = inout(reg) b.data.as_ptr().wrapping_add(self.b1) => _,
                lda = in(reg) lda,
                ldb = in(reg) ldb,
                bstep = in(reg) 16 * ldb,
                kk = inout(reg) chunks => _,
                options(nostack, readonly)
            );
            asm!("tilestored [{c} + {ldc}*1], tmm0", c = in(reg) c0, ldc = in(reg) ldc_bytes, options(nostack));
            if cols2 {
                asm!("tilestored [{c} + {ldc}*1 + 64], tmm1", c = in(reg) c0, ldc = in(reg) ldc_bytes, options(nostack));
            }
            if rows2 {
                asm!("tilestored [{c} + {ldc}*1], tmm2", c = in(reg) c1, ldc = in(reg) ldc_bytes, options(nostack));
            }
            if rows2 && cols2 {
                asm!("tilestored [{c} + {ldc}*1 + 64], tmm3", c = in(reg) c1, ldc = in(reg) ldc_bytes, options(nostack));
            }
        }
    }

    #[cfg(not(target_arch = "x86_64"))]
    #[allow(clippy::too_many_arguments)]
    unsafe fn run(&self, _: &mut [f32], _: usize, _: bool, _: &[u16], _: usize, _: usize, _: &PackedB) {
        unreachable!("AMX is never available off x86_64")
    }
}

#[cfg(not(target_arch = "x86_64"))]
unsafe fn load_config(_: &TileConfig) {}

#[cfg(not(target_arch = "x86_64"))]
unsafe fn release() {}
