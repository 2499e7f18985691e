//! A bounding-volume hierarchy over the scene objects: median splits on the
//! longest axis of the centroids, two objects per leaf at most.

use crate::primitives::{Aabb, PrimHit, Ray, Shape};

const LEAF_SIZE: usize = 2;

#[derive(Debug, Clone)]
enum Node {
    Leaf { start: usize, end: usize },
    Inner { left: usize, right: usize },
}

/// The hierarchy: nodes with their bounds, and the object order of the leaves.
#[derive(Debug, Clone, Default)]
pub(crate) struct Bvh {
    nodes: Vec<(Aabb, Node)>,
    order: Vec<usize>,
}

impl Bvh {
    /// Builds the hierarchy over `shapes` (indices are kept as object ids).
    pub(crate) fn build(shapes: &[Shape]) -> Bvh {
        let mut bvh = Bvh {
            nodes: Vec::new(),
            order: (0..shapes.len()).collect(),
        };
        if !shapes.is_empty() {
            let bounds: Vec<Aabb> = shapes.iter().map(Shape::bounds).collect();
            bvh.build_node(&bounds, 0, shapes.len());
        }
        bvh
    }

    fn build_node(&mut self, bounds: &[Aabb], start: usize, end: usize) -> usize {
        let items = &mut self.order[start..end];
        let all = items
            .iter()
            .map(|&i| bounds[i])
            .reduce(Aabb::union)
            .unwrap_or(bounds[0]);
        let id = self.nodes.len();
        if end - start <= LEAF_SIZE {
            self.nodes.push((all, Node::Leaf { start, end }));
            return id;
        }
        let centres = items
            .iter()
            .map(|&i| {
                let c = bounds[i].centre();
                Aabb { min: c, max: c }
            })
            .reduce(Aabb::union)
            .unwrap_or(all);
        let extent = centres.max - centres.min;
        let axis = if extent.x >= extent.y && extent.x >= extent.z {
            0
        } else if extent.y >= extent.z {
            1
        } else {
            2
        };
        items.sort_by(|&a, &b| {
            let (ca, cb) = (bounds[a].centre().axis(axis), bounds[b].centre().axis(axis));
            ca.total_cmp(&cb).then(a.cmp(&b))
        });
        let mid = start + (end - start) / 2;
        self.nodes.push((all, Node::Leaf { start, end }));
        let left = self.build_node(bounds, start, mid);
        let right = self.build_node(bounds, mid, end);
        self.nodes[id].1 = Node::Inner { left, right };
        id
    }

    /// The nearest hit in `(t_min, t_max)`, with the object id.
    pub(crate) fn closest(
        &self,
        shapes: &[Shape],
        ray: &Ray,
        t_min: f64,
        t_max: f64,
    ) -> Option<(PrimHit, usize)> {
        let mut best: Option<(PrimHit, usize)> = None;
        let mut limit = t_max;
        self.visit(ray, t_min, &mut limit, |i, limit| {
            if let Some(hit) = shapes[i].intersect(ray, t_min, *limit) {
                *limit = hit.t;
                best = Some((hit, i));
            }
            false
        });
        best
    }

    /// Whether any object is hit in `(t_min, t_max)`.
    pub(crate) fn any(&self, shapes: &[Shape], ray: &Ray, t_min: f64, t_max: f64) -> bool {
        let mut limit = t_max;
        self.visit(ray, t_min, &mut limit, |i, limit| {
            shapes[i].intersect(ray, t_min, *limit).is_some()
        })
    }

    /// Depth-first traversal; `leaf(object, limit)` may shrink the limit and
    /// returns true to stop early. Returns whether it stopped early.
    fn visit(
        &self,
        ray: &Ray,
        t_min: f64,
        limit: &mut f64,
        mut leaf: impl FnMut(usize, &mut f64) -> bool,
    ) -> bool {
        if self.nodes.is_empty() {
            return false;
        }
        // Median splits keep the depth at log2(objects) + 1, far below 64.
        let mut stack = [0usize; 64];
        let mut len = 1;
        while len > 0 {
            len -= 1;
            let (bounds, node) = &self.nodes[stack[len]];
            if !bounds.hit_by(ray, t_min, *limit) {
                continue;
            }
            match *node {
                Node::Leaf { start, end } => {
                    for &i in &self.order[start..end] {
                        if leaf(i, limit) {
                            return true;
                        }
                    }
                }
                Node::Inner { left, right } => {
                    stack[len] = right;
                    stack[len + 1] = left;
                    len += 2;
                }
            }
        }
        false
    }
}
