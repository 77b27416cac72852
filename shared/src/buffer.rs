//! How the traversal reads a scene's buffers: each one a plain slice (one storage buffer on
//! the GPU), or split into equal power-of-two chunks bound side by side, when a buffer is
//! larger than one binding may be.
//!
//! The traversal is generic over [`Buffer`], so both forms run the same code: a plain slice
//! compiles to the indexing it always was, and a [`Split`] buffer finds the chunk of each
//! element. Every buffer of a split scene starts at a chunk of its own, so an element's
//! address within its buffer stays a `u32` and a struct (8-word nodes, 4-word headers) never
//! straddles two chunks. The CPU can read a scene split the same way, through the same chunks
//! taken as slices of its own buffers: that is how the split path is tested against the GPU.

use core::marker::PhantomData;

use crate::layout::{BvhNode, GridHeader, SplitParams};

/// What code that reads a scene carries, one bit per part of the traversal (see
/// [`Buffer::carries`]). Natively every part; a GPU kernel carries what its words say (see
/// [`KernelWords`]), and the code of the parts it leaves out is folded away: a shader
/// compiler keeps a part's registers and scratch memory even where no ray takes it.
pub mod carries {
    /// The formats made for displaced grids that plain grids may ask for too: tight headers
    /// and relative radii.
    pub const DISPLACED_FORMATS: u32 = 1;
    /// What displaced grids alone hold: their values, spheres at each grid's own level, leaf
    /// radius pairs and the wide top level's walk.
    pub const DISPLACED_GRIDS: u32 = 2;
    /// The decoder of compressed displacement values (see `crate::compressed_values`).
    pub const DECODER: u32 = 4;
    /// Only grids of compressed values: every other vertex format left out, so that a shader
    /// inlines far less at each vertex read.
    pub const ONLY_COMPRESSED: u32 = 8;
    /// The walk down a grid's sphere hierarchy with a stack of sub-triangles (any depth).
    pub const STACK: u32 = 16;
    /// The root's visit alone, without a stack, for grids whose stored leaves are the root's
    /// children or the root (`GridParams::one_visit`), which it walks where both are carried.
    pub const ONE_VISIT: u32 = 32;
    /// The smooth normals a render may light its hits with (`FrameParams::smooth_normals`):
    /// the render's largest code outside the traversal, which a frame without them leaves
    /// out (grids then light with their geometric normals).
    pub const SMOOTH_NORMALS: u32 = 64;
    /// Everything but [`ONLY_COMPRESSED`]: what the CPU carries.
    pub const ALL: u32 = DISPLACED_FORMATS | DISPLACED_GRIDS | DECODER | STACK | ONE_VISIT | SMOOTH_NORMALS;
}

/// Random read access to the elements of a buffer.
pub trait Buffer<T>: Copy {
    /// The most that code reading these words may carry, a constant: the parts outside it are
    /// left out of a kernel's module (see [`KernelWords`]).
    const MOST: u32 = carries::ALL;

    /// What code reading these words carries: bits of [`carries`], within [`Self::MOST`].
    /// Natively [`carries::ALL`]; a GPU kernel's words say it through [`KernelWords`].
    #[inline(always)]
    fn carries(self) -> u32 {
        carries::ALL
    }

    fn load(self, index: u32) -> T;
    fn is_empty(self) -> bool;

    /// Elements `first .. first + 3`.
    #[inline(always)]
    fn load3(self, first: u32) -> [T; 3] {
        [self.load(first), self.load(first + 1), self.load(first + 2)]
    }
}

/// Element `i` of a buffer: bounds-checked natively, where a read out of bounds is a bug that
/// panics; unchecked in a shader, where wgpu's translation of the module already keeps every
/// index within its buffer, and a check of Rust's own would inline a branch and a panic into
/// every read (a shader inlines every read of its traversal).
#[cfg(not(target_arch = "spirv"))]
#[inline(always)]
pub fn element<T: Copy>(buffer: &[T], i: usize) -> T {
    buffer[i]
}

/// `element` in a shader: unchecked.
#[cfg(target_arch = "spirv")]
#[inline(always)]
pub fn element<T: Copy>(buffer: &[T], i: usize) -> T {
    use spirv_std::arch::IndexUnchecked;
    // SAFETY: wgpu's translation of the module keeps every index within its buffer.
    unsafe { *buffer.index_unchecked(i) }
}

impl<T: Copy> Buffer<T> for &[T] {
    #[inline(always)]
    fn load(self, index: u32) -> T {
        element(self, index as usize)
    }

    /// Indexed in `usize`, so that the compiler sees three neighbours (one bounds check).
    #[inline(always)]
    fn load3(self, first: u32) -> [T; 3] {
        let i = first as usize;
        [element(self, i), element(self, i + 1), element(self, i + 2)]
    }

    #[inline(always)]
    fn is_empty(self) -> bool {
        self.len() == 0
    }
}

/// A few words held in registers (e.g. a grid's header fields once loaded).
impl<T: Copy, const N: usize> Buffer<T> for &[T; N] {
    #[inline(always)]
    fn load(self, index: u32) -> T {
        self[index as usize]
    }

    #[inline(always)]
    fn is_empty(self) -> bool {
        N == 0
    }
}

/// A scene's words as a GPU kernel reads them: what its code carries is `MOST &
/// carries` (see [`carries`]). `MOST`, a constant of the kernel's own, leaves parts out of the
/// module itself; `carries`, from the kernel's specialisation constants, leaves parts out of
/// each pipeline the driver makes from it, the host choosing them for the scene.
#[derive(Copy, Clone)]
pub struct KernelWords<B, const MOST: u32> {
    pub words: B,
    pub carries: u32,
}

impl<B: Buffer<u32>, const MOST: u32> Buffer<u32> for KernelWords<B, MOST> {
    const MOST: u32 = MOST;

    #[inline(always)]
    fn carries(self) -> u32 {
        MOST & self.carries
    }

    #[inline(always)]
    fn load(self, index: u32) -> u32 {
        self.words.load(index)
    }

    #[inline(always)]
    fn load3(self, first: u32) -> [u32; 3] {
        self.words.load3(first)
    }

    #[inline(always)]
    fn is_empty(self) -> bool {
        self.words.is_empty()
    }
}

/// Most chunks a split scene may use. Their bindings come after a kernel's own (parameters,
/// static list, rays and hits, or image), in a set of their own. Eight bind eight times a
/// binding's bytes, gigabytes where bindings reach hundreds of megabytes; every read of a
/// split buffer picks its chunk through `log2` of this many two-way branches (see
/// [`Chunks::read`]).
pub const SPLIT_CHUNKS: u32 = 8;

/// The chunks of a split scene, each a run of words (unused ones empty). A shader cannot
/// index an array of buffer references, so each chunk is a field of its own.
#[derive(Copy, Clone)]
pub struct Chunks<'a> {
    pub c0: &'a [u32],
    pub c1: &'a [u32],
    pub c2: &'a [u32],
    pub c3: &'a [u32],
    pub c4: &'a [u32],
    pub c5: &'a [u32],
    pub c6: &'a [u32],
    pub c7: &'a [u32],
}

const _: () = assert!(SPLIT_CHUNKS == 8, "Chunks has a field and a branch per chunk");

impl<'a> Chunks<'a> {
    /// Word `offset` of chunk `chunk`.
    #[inline(always)]
    pub fn word(&self, chunk: u32, offset: u32) -> u32 {
        let o = offset as usize;
        self.read(chunk, |words| element(words, o))
    }

    /// Words `offset .. offset + 4` of chunk `chunk`, under one choice of chunk: a shader
    /// then picks the chunk once for a whole header or half a node instead of once per word.
    #[inline(always)]
    pub fn word4(&self, chunk: u32, offset: u32) -> [u32; 4] {
        let o = offset as usize;
        self.read(chunk, |words| {
            [
                element(words, o),
                element(words, o + 1),
                element(words, o + 2),
                element(words, o + 3),
            ]
        })
    }

    /// `read` applied to chunk `chunk` (the last one for any larger number), chosen by a
    /// binary tree of two-way branches. Not a `match`: a shader compiler keeps the registers
    /// of every arm of a multi-way switch over reads from different buffers (the split
    /// kernels spilled), while two-way branches over reads it folds into one read.
    #[inline(always)]
    fn read<T>(&self, chunk: u32, read: impl Fn(&'a [u32]) -> T) -> T {
        let pick = |first: &'a [u32], second: &'a [u32], take_second: bool| {
            if take_second {
                read(second)
            } else {
                read(first)
            }
        };
        if chunk < 4 {
            if chunk < 2 {
                pick(self.c0, self.c1, chunk == 1)
            } else {
                pick(self.c2, self.c3, chunk == 3)
            }
        } else if chunk < 6 {
            pick(self.c4, self.c5, chunk == 5)
        } else {
            pick(self.c6, self.c7, chunk >= 7)
        }
    }

    /// Chunks from a list of at most [`SPLIT_CHUNKS`] slices; the rest are empty.
    #[cfg(not(target_arch = "spirv"))]
    pub fn from_slices(parts: &[&'a [u32]]) -> Self {
        assert!(
            parts.len() <= SPLIT_CHUNKS as usize,
            "more chunks than a split scene has"
        );
        let part = |k: usize| parts.get(k).copied().unwrap_or(&[]);
        Chunks {
            c0: part(0),
            c1: part(1),
            c2: part(2),
            c3: part(3),
            c4: part(4),
            c5: part(5),
            c6: part(6),
            c7: part(7),
        }
    }
}

/// Buffer `buffer` of a split scene (its index in [`SplitParams`]), read as elements of `T`.
#[derive(Copy, Clone)]
pub struct Split<'a, T> {
    /// By value: a reference to the caller's `Chunks` would be a pointer to a function
    /// variable inside a struct, which shaders cannot hold.
    chunks: Chunks<'a>,
    first_chunk: u32,
    shift: u32,
    len: u32,
    item: PhantomData<T>,
}

impl<'a, T> Split<'a, T> {
    #[inline(always)]
    pub fn new(chunks: &Chunks<'a>, params: &SplitParams, buffer: usize) -> Self {
        Split {
            chunks: *chunks,
            first_chunk: params.first_chunk[buffer],
            shift: params.chunk_shift,
            len: params.len[buffer],
            item: PhantomData,
        }
    }

    /// Word `offset` of the element that starts at word `word` of the buffer.
    #[inline(always)]
    fn word(&self, word: u32, offset: u32) -> u32 {
        let mask = (1u32 << self.shift) - 1;
        let (chunk, at) = (self.first_chunk + (word >> self.shift), (word & mask) + offset);
        self.chunks.word(chunk, at)
    }

    /// Words `word .. word + 4`, which lie in one chunk (`word` a multiple of 4: chunks hold
    /// a power of two words, at least four).
    #[inline(always)]
    fn word4(&self, word: u32) -> [u32; 4] {
        let mask = (1u32 << self.shift) - 1;
        let (chunk, at) = (self.first_chunk + (word >> self.shift), word & mask);
        self.chunks.word4(chunk, at)
    }
}

impl Buffer<u32> for Split<'_, u32> {
    #[inline(always)]
    fn load(self, index: u32) -> u32 {
        self.word(index, 0)
    }

    #[inline(always)]
    fn is_empty(self) -> bool {
        self.len == 0
    }
}

impl Buffer<f32> for Split<'_, f32> {
    #[inline(always)]
    fn load(self, index: u32) -> f32 {
        f32::from_bits(self.word(index, 0))
    }

    #[inline(always)]
    fn is_empty(self) -> bool {
        self.len == 0
    }
}

impl Buffer<BvhNode> for Split<'_, BvhNode> {
    #[inline(always)]
    fn load(self, index: u32) -> BvhNode {
        let [x0, y0, z0, first] = self.word4(8 * index);
        let [x1, y1, z1, count] = self.word4(8 * index + 4);
        let f = f32::from_bits;
        BvhNode {
            min: [f(x0), f(y0), f(z0)],
            first,
            max: [f(x1), f(y1), f(z1)],
            count,
        }
    }

    #[inline(always)]
    fn is_empty(self) -> bool {
        self.len == 0
    }
}

impl Buffer<GridHeader> for Split<'_, GridHeader> {
    #[inline(always)]
    fn load(self, index: u32) -> GridHeader {
        let [e0, e1, c0, c1] = self.word4(4 * index);
        GridHeader {
            edges: [e0, e1],
            corners: [c0, c1],
        }
    }

    #[inline(always)]
    fn is_empty(self) -> bool {
        self.len == 0
    }
}
