//! What a ray's traversal costs, counted for the cost heat map: top-level (or baseline) BVH
//! nodes, spheres and micro-triangles tested.
//!
//! The traversal takes its counter as a type parameter: [`Uncounted`] does nothing and
//! compiles away, so only the heat map's own kernels and CPU loop carry counters.

/// Where the traversal reports the tests it makes.
pub trait Tally {
    /// `n` BVH node boxes tested.
    fn nodes(&mut self, n: u32);
    /// `n` spheres of a grid hierarchy tested.
    fn spheres(&mut self, n: u32);
    /// `n` triangles given the full ray-triangle test.
    fn triangles(&mut self, n: u32);
}

/// No counting: every call is empty.
#[derive(Copy, Clone, Default)]
pub struct Uncounted;

impl Tally for Uncounted {
    #[inline(always)]
    fn nodes(&mut self, _n: u32) {}
    #[inline(always)]
    fn spheres(&mut self, _n: u32) {}
    #[inline(always)]
    fn triangles(&mut self, _n: u32) {}
}

/// The tests of one ray, counted.
#[repr(C)]
#[derive(Copy, Clone, Default)]
#[cfg_attr(not(target_arch = "spirv"), derive(Debug, PartialEq, Eq))]
pub struct Costs {
    pub nodes: u32,
    pub spheres: u32,
    pub triangles: u32,
}

/// Largest count each field keeps when packed: 10 bits of nodes, 11 of spheres, 11 of
/// triangles.
pub const MAX_PACKED_NODES: u32 = (1 << 10) - 1;
pub const MAX_PACKED_SPHERES: u32 = (1 << 11) - 1;
pub const MAX_PACKED_TRIANGLES: u32 = (1 << 11) - 1;

impl Costs {
    /// One word, each count saturating at its field's largest value.
    #[inline]
    pub fn pack(&self) -> u32 {
        let nodes = if self.nodes < MAX_PACKED_NODES {
            self.nodes
        } else {
            MAX_PACKED_NODES
        };
        let spheres = if self.spheres < MAX_PACKED_SPHERES {
            self.spheres
        } else {
            MAX_PACKED_SPHERES
        };
        let triangles = if self.triangles < MAX_PACKED_TRIANGLES {
            self.triangles
        } else {
            MAX_PACKED_TRIANGLES
        };
        nodes | (spheres << 10) | (triangles << 21)
    }

    #[inline]
    pub fn unpack(word: u32) -> Costs {
        Costs {
            nodes: word & MAX_PACKED_NODES,
            spheres: (word >> 10) & MAX_PACKED_SPHERES,
            triangles: word >> 21,
        }
    }

    /// Every test, whatever its kind.
    #[inline]
    pub fn total(&self) -> u32 {
        self.nodes + self.spheres + self.triangles
    }
}

impl Tally for Costs {
    #[inline(always)]
    fn nodes(&mut self, n: u32) {
        self.nodes += n;
    }
    #[inline(always)]
    fn spheres(&mut self, n: u32) {
        self.spheres += n;
    }
    #[inline(always)]
    fn triangles(&mut self, n: u32) {
        self.triangles += n;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn packing_round_trips_and_saturates() {
        let c = Costs {
            nodes: 700,
            spheres: 2000,
            triangles: 1500,
        };
        assert_eq!(Costs::unpack(c.pack()), c);
        let big = Costs {
            nodes: 5000,
            spheres: 5000,
            triangles: 5000,
        };
        let back = Costs::unpack(big.pack());
        assert_eq!((back.nodes, back.spheres, back.triangles), (1023, 2047, 2047));
    }
}
