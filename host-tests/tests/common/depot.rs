//! The committed compiled depot map (`boards/qemu-mps2-an386/depot.map`,
//! with its localization field), in 8-byte-aligned storage as a compiled map
//! is read in place.

use echoloc::map::MapView;

pub fn root() -> std::path::PathBuf {
    std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..")
}

pub struct Depot {
    pub words: Vec<u64>,
    pub len: usize,
}

impl Depot {
    pub fn load() -> Self {
        let bytes = std::fs::read(root().join("boards/qemu-mps2-an386/depot.map")).unwrap();
        let mut words = vec![0u64; bytes.len().div_ceil(8)];
        bytemuck::cast_slice_mut::<u64, u8>(&mut words)[..bytes.len()].copy_from_slice(&bytes);
        Self { words, len: bytes.len() }
    }

    #[allow(dead_code)]
    pub fn bytes(&self) -> &[u8] {
        &bytemuck::cast_slice::<u64, u8>(&self.words)[..self.len]
    }

    pub fn view(&self) -> MapView<'_> {
        MapView::new(&bytemuck::cast_slice::<u64, u8>(&self.words)[..self.len]).unwrap()
    }
}
