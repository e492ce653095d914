// The triangle of a work item, for the modules whose passes spread each triangle's work over a run of work items:
// voxelize (the surface walk), solid (the crossing passes), distance (the band) and colour (the candidates' rows). Each of them declares
// `first_items`, triangle t's first work item at index t (ascending, a prefix sum of the triangles' item counts), so
// the search is written once. The CPU has no counterpart: it walks each triangle's items in turn.

// The last of the `count` triangles whose first work item is at most `item` (binary search).
fn item_triangle(item: u32, count: u32) -> u32 {
    var lo = 0u;
    var hi = count;
    while hi - lo > 1u {
        let mid = (lo + hi) / 2u;
        if first_items[mid] <= item {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    return lo;
}
