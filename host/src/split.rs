//! A scene's buffers cut into chunks for a device whose bindings are smaller than the buffers
//! (see `gridrt_shared::buffer`): each buffer starts a chunk of its own, every chunk but a
//! buffer's last is `chunk_words` words, and the chunks are slices of the scene's own
//! buffers, so nothing is copied on the host. The GPU binds them side by side; the CPU reads
//! them through the same shared code to check it.

use crate::error::{fail, Result};
use gridrt_shared::buffer::{Chunks, Split, SPLIT_CHUNKS};
use gridrt_shared::grid_index::MICRO_TRIANGLES;
use gridrt_shared::grid_traverse;
use gridrt_shared::layout::{BvhNode, FrameParams, SplitParams, GRID_NODES, TRIANGLE_NODES};
use gridrt_shared::top_nodes::TopNodes;
use gridrt_shared::traverse::TriangleMesh;

use crate::backend::cpu::render_pixels;
use crate::limits::BufferSize;
use crate::scene::Scene;

/// One of a scene's large buffers, as words.
pub struct SceneBuffer<'a> {
    pub name: &'static str,
    pub words: &'a [u32],
    /// Elements (nodes, headers, words or floats): what the traversal indexes.
    pub len: u32,
}

impl SceneBuffer<'_> {
    pub fn size(&self) -> BufferSize {
        BufferSize {
            name: self.name,
            bytes: self.words.len() as u64 * 4,
            at_least: false,
        }
    }
}

/// A scene's large buffers in the order of `gridrt_shared::layout::SplitParams` (the grids'
/// static index list is not among them: it is small, and bound on its own).
pub fn scene_buffers(scene: &Scene) -> Vec<SceneBuffer<'_>> {
    fn buffer<'a, T: bytemuck::Pod>(name: &'static str, items: &'a [T]) -> SceneBuffer<'a> {
        SceneBuffer {
            name,
            words: bytemuck::cast_slice(items),
            len: items.len() as u32,
        }
    }
    match scene {
        Scene::Triangles(s) => vec![
            buffer("BVH", &s.nodes),
            buffer("vertex", &s.positions),
            buffer("index", &s.indices),
        ],
        Scene::Grids(s) => vec![
            buffer("top-level BVH", &s.nodes),
            buffer("grid header", &s.headers),
            buffer("grid vertex", &s.vertices),
            buffer("sphere radius", &s.radii),
        ],
    }
}

/// Chunks of `chunk_words` words the buffers take (one at least each, so that every buffer
/// has a binding).
pub fn chunks_needed(sizes: &[BufferSize], chunk_words: u32) -> u64 {
    sizes
        .iter()
        .map(|b| b.bytes.div_ceil(4).div_ceil(chunk_words as u64).max(1))
        .sum()
}

/// Refuses buffers that need more than `most` chunks of `chunk_words` words, naming each
/// buffer and its size; `device` names where the chunk size comes from.
pub fn check_chunks(sizes: &[BufferSize], chunk_words: u32, most: u32, device: &str) -> Result<()> {
    let needed = chunks_needed(sizes, chunk_words);
    if needed <= most as u64 {
        return Ok(());
    }
    let at_least = if sizes.iter().any(|b| b.at_least) {
        "at least "
    } else {
        ""
    };
    let sizes: Vec<String> = sizes.iter().map(|b| format!("{} {}", b.name, b.bytes_text())).collect();
    fail!(
        Limits,
        "the scene's buffers ({}) need {at_least}{needed} bindings of {} bytes, more than the {most} that \
         gridrt binds on {device}; use fewer levels or --backend cpu",
        sizes.join(", "),
        chunk_words as u64 * 4,
    );
}

/// A scene's buffers in chunks.
pub struct SplitScene<'a> {
    pub params: SplitParams,
    pub chunks: Vec<&'a [u32]>,
}

/// The largest power-of-two chunk (in words) that a binding of `limit` bytes holds.
pub fn chunk_words(limit: u64) -> u32 {
    let words = (limit / 4).clamp(8, 1 << 31);
    1 << (63 - words.leading_zeros())
}

/// Cuts `scene`'s buffers into chunks of `chunk_words` words (a power of two, at least 8, so
/// that no node or header straddles two). Fails, naming every buffer and its size, when they
/// need more than [`SPLIT_CHUNKS`]; `device` names where that limit comes from.
pub fn split<'a>(scene: &'a Scene, chunk_words: u32, device: &str) -> Result<SplitScene<'a>> {
    assert!(
        chunk_words.is_power_of_two() && chunk_words >= 8,
        "chunks of {chunk_words} words"
    );
    let buffers = scene_buffers(scene);
    let sizes: Vec<BufferSize> = buffers.iter().map(SceneBuffer::size).collect();
    check_chunks(&sizes, chunk_words, SPLIT_CHUNKS, device)?;
    let mut params = SplitParams {
        chunk_shift: chunk_words.trailing_zeros(),
        ..Default::default()
    };
    let mut chunks = Vec::new();
    for (b, buffer) in buffers.iter().enumerate() {
        params.first_chunk[b] = chunks.len() as u32;
        params.len[b] = buffer.len;
        // Addresses within a buffer are 32-bit words.
        if buffer.words.len() as u64 > u32::MAX as u64 {
            fail!(
                Limits,
                "the {} buffer needs {} bytes, more than the 16 GiB a buffer can address; use fewer levels",
                buffer.name,
                buffer.words.len() as u64 * 4
            );
        }
        chunks.extend(buffer.words.chunks(chunk_words as usize));
        if buffer.words.is_empty() {
            // A chunk of its own all the same, so every buffer has a binding.
            chunks.push(&[]);
        }
    }
    Ok(SplitScene { params, chunks })
}

/// Renders on the CPU from a scene's buffers cut into chunks, read the way the GPU reads a
/// split scene: the same image as [`crate::backend::cpu::render_cpu`], by other addressing.
pub fn render_cpu_split(scene: &Scene, split: &SplitScene, frame: &FrameParams) -> Vec<u32> {
    let chunks = Chunks::from_slices(&split.chunks);
    let nodes = |b| Split::<BvhNode>::new(&chunks, &split.params, b);
    match scene {
        Scene::Triangles(_) => {
            let mesh = TriangleMesh::split(&chunks, &split.params);
            render_pixels(frame, nodes(TRIANGLE_NODES), &mesh)
        }
        Scene::Grids(_) => {
            let grids = grid_traverse::GridScene::split(&chunks, &split.params, &MICRO_TRIANGLES, frame.grid);
            render_pixels(frame, TopNodes::new(nodes(GRID_NODES)), &grids)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn chunks_are_the_largest_power_of_two_that_fits() {
        assert_eq!(chunk_words(128 << 20), 1 << 25);
        assert_eq!(chunk_words((128 << 20) - 4), 1 << 24);
        assert_eq!(chunk_words(100), 16);
        assert_eq!(chunk_words(4), 8);
        assert_eq!(chunk_words(u64::MAX), 1 << 31);
    }
}
