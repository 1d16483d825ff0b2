//! The stable colour of a track id, shared by every picture probmot draws (PNG plots, Rerun
//! recordings, the Foxglove SceneUpdate output), so that an id has one colour everywhere.

/// Colours given to ids, picked by [`id_color`]: Tableau 10 without its grey, and four dark
/// colours that stay apart from them on white. `scripts/to_rerun.py` uses the same table and hash,
/// so an id has one colour in both pictures.
pub const PALETTE: [(u8, u8, u8); 13] = [
    (0x1f, 0x77, 0xb4),
    (0xff, 0x7f, 0x0e),
    (0x2c, 0xa0, 0x2c),
    (0xd6, 0x27, 0x28),
    (0x94, 0x67, 0xbd),
    (0x8c, 0x56, 0x4b),
    (0xe3, 0x77, 0xc2),
    (0xbc, 0xbd, 0x22),
    (0x17, 0xbe, 0xcf),
    (0x1a, 0x1a, 0x80),
    (0x00, 0x80, 0x80),
    (0x7f, 0x00, 0x00),
    (0x99, 0x00, 0x66),
];

/// SplitMix64 finaliser: a fixed, well-mixed hash of an id (stable across runs, platforms and
/// Rust versions, unlike `std`'s hashers).
pub fn mix64(id: u64) -> u64 {
    let mut z = id.wrapping_add(0x9e37_79b9_7f4a_7c15);
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// The colour of an id: a stable hash of it into [`PALETTE`].
pub fn id_color(id: u64) -> (u8, u8, u8) {
    PALETTE[(mix64(id) % PALETTE.len() as u64) as usize]
}
