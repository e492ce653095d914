//! rayon's calls as meshvox makes them, done in order on the calling thread: the page's stand-in for rayon
//! (wasm32 only, where there is one thread and no pool to make; [`crate::parallel`] re-exports rayon everywhere
//! else). The page's wasm then carries no thread pool, job queue, work splitting or parallel sort. The results are
//! the parallel loops' own: meshvox's parallel reductions are associative and its loops write disjoint pieces.
//! Only what the library calls is here; a new rayon call fails the wasm32 build until it is added.

use std::iter::{Enumerate, Filter, FilterMap, FlatMap, Map, Once};

/// rayon::join: `a` then `b`.
pub fn join<A: FnOnce() -> RA, B: FnOnce() -> RB, RA, RB>(a: A, b: B) -> (RA, RB) {
    (a(), b())
}

/// The one thread.
pub fn current_num_threads() -> usize {
    1
}

/// Not a pool's worker.
pub fn current_thread_index() -> Option<usize> {
    None
}

/// A sequential iterator with the adapters of rayon's parallel iterators (with rayon's signatures where they
/// differ from `Iterator`'s: `fold` and `reduce` take an identity); the rest is `Iterator`'s.
pub struct Seq<I>(I);

impl<I: Iterator> Iterator for Seq<I> {
    type Item = I::Item;

    fn next(&mut self) -> Option<I::Item> {
        self.0.next()
    }

    fn size_hint(&self) -> (usize, Option<usize>) {
        self.0.size_hint()
    }
}

impl<I: Iterator> Seq<I> {
    pub fn map<B, F: FnMut(I::Item) -> B>(self, f: F) -> Seq<Map<I, F>> {
        Seq(self.0.map(f))
    }

    pub fn filter<P: FnMut(&I::Item) -> bool>(self, p: P) -> Seq<Filter<I, P>> {
        Seq(self.0.filter(p))
    }

    pub fn filter_map<B, F: FnMut(I::Item) -> Option<B>>(self, f: F) -> Seq<FilterMap<I, F>> {
        Seq(self.0.filter_map(f))
    }

    pub fn enumerate(self) -> Seq<Enumerate<I>> {
        Seq(self.0.enumerate())
    }

    pub fn zip<J: IntoParallelIterator>(self, other: J) -> Seq<std::iter::Zip<I, J::Iter>> {
        Seq(self.0.zip(other.into_par_iter().0))
    }

    pub fn flat_map_iter<U: IntoIterator, F: FnMut(I::Item) -> U>(self, f: F) -> Seq<FlatMap<I, U, F>> {
        Seq(self.0.flat_map(f))
    }

    pub fn with_min_len(self, _: usize) -> Self {
        self
    }

    /// rayon's fold: one accumulator from `identity`, folded over every item, as a one-item iterator.
    pub fn fold<T, Id: Fn() -> T, F: FnMut(T, I::Item) -> T>(self, identity: Id, f: F) -> Seq<Once<T>> {
        Seq(std::iter::once(self.0.fold(identity(), f)))
    }

    /// rayon's reduce: the items combined with `op`, starting from `identity`.
    pub fn reduce<Id: Fn() -> I::Item, F: FnMut(I::Item, I::Item) -> I::Item>(self, identity: Id, op: F) -> I::Item {
        self.0.fold(identity(), op)
    }

    /// rayon's try_reduce over options: `None` as soon as an item is `None`, else the values combined with `op`.
    pub fn try_reduce<T, Id: Fn() -> T, F: FnMut(T, T) -> Option<T>>(mut self, identity: Id, mut op: F) -> Option<T>
    where
        I: Iterator<Item = Option<T>>,
    {
        self.0.try_fold(identity(), |acc, item| op(acc, item?))
    }

    pub fn position_first<P: FnMut(I::Item) -> bool>(mut self, p: P) -> Option<usize> {
        self.0.position(p)
    }

    pub fn collect_into_vec(self, out: &mut Vec<I::Item>) {
        out.clear();
        out.extend(self.0);
    }
}

/// `into_par_iter`: ranges, vectors, tuples (zipped, as rayon's MultiZip) and these iterators themselves.
pub trait IntoParallelIterator {
    type Iter: Iterator<Item = Self::Item>;
    type Item;
    fn into_par_iter(self) -> Seq<Self::Iter>;
}

impl<I: Iterator> IntoParallelIterator for Seq<I> {
    type Iter = I;
    type Item = I::Item;
    fn into_par_iter(self) -> Seq<I> {
        self
    }
}

impl<T> IntoParallelIterator for std::ops::Range<T>
where
    std::ops::Range<T>: Iterator<Item = T>,
{
    type Iter = std::ops::Range<T>;
    type Item = T;
    fn into_par_iter(self) -> Seq<Self::Iter> {
        Seq(self)
    }
}

impl<T> IntoParallelIterator for Vec<T> {
    type Iter = std::vec::IntoIter<T>;
    type Item = T;
    fn into_par_iter(self) -> Seq<Self::Iter> {
        Seq(self.into_iter())
    }
}

impl<'a, T> IntoParallelIterator for &'a [T] {
    type Iter = std::slice::Iter<'a, T>;
    type Item = &'a T;
    fn into_par_iter(self) -> Seq<Self::Iter> {
        Seq(self.iter())
    }
}

impl<'a, T> IntoParallelIterator for &'a Vec<T> {
    type Iter = std::slice::Iter<'a, T>;
    type Item = &'a T;
    fn into_par_iter(self) -> Seq<Self::Iter> {
        Seq(self.iter())
    }
}

/// Tuples of iterables, zipped: items are tuples of the same arity (the arities the library zips).
macro_rules! zipped_tuple {
    ($name:ident: $($t:ident $i:tt),+) => {
        pub struct $name<$($t),+>($($t),+);

        impl<$($t: Iterator),+> Iterator for $name<$($t),+> {
            type Item = ($($t::Item),+);
            fn next(&mut self) -> Option<Self::Item> {
                Some(($(self.$i.next()?),+))
            }
        }

        impl<$($t: IntoParallelIterator),+> IntoParallelIterator for ($($t),+) {
            type Iter = $name<$($t::Iter),+>;
            type Item = ($($t::Item),+);
            fn into_par_iter(self) -> Seq<Self::Iter> {
                Seq($name($(self.$i.into_par_iter().0),+))
            }
        }
    };
}
zipped_tuple!(Zip2: A 0, B 1);
zipped_tuple!(Zip6: A 0, B 1, C 2, D 3, E 4, F 5);

/// `par_iter` on anything whose reference iterates (slices, vectors, maps).
pub trait IntoParallelRefIterator<'a> {
    type Iter: Iterator;
    fn par_iter(&'a self) -> Seq<Self::Iter>;
}

impl<'a, C: ?Sized + 'a> IntoParallelRefIterator<'a> for C
where
    &'a C: IntoIterator,
{
    type Iter = <&'a C as IntoIterator>::IntoIter;
    fn par_iter(&'a self) -> Seq<Self::Iter> {
        Seq(self.into_iter())
    }
}

/// `par_iter_mut` on anything whose mutable reference iterates.
pub trait IntoParallelRefMutIterator<'a> {
    type Iter: Iterator;
    fn par_iter_mut(&'a mut self) -> Seq<Self::Iter>;
}

impl<'a, C: ?Sized + 'a> IntoParallelRefMutIterator<'a> for C
where
    &'a mut C: IntoIterator,
{
    type Iter = <&'a mut C as IntoIterator>::IntoIter;
    fn par_iter_mut(&'a mut self) -> Seq<Self::Iter> {
        Seq(self.into_iter())
    }
}

/// rayon's slice methods.
pub trait ParallelSlice<T> {
    fn par_chunks(&self, size: usize) -> Seq<std::slice::Chunks<'_, T>>;
    fn par_chunks_exact(&self, size: usize) -> Seq<std::slice::ChunksExact<'_, T>>;
}

impl<T> ParallelSlice<T> for [T] {
    fn par_chunks(&self, size: usize) -> Seq<std::slice::Chunks<'_, T>> {
        Seq(self.chunks(size))
    }

    fn par_chunks_exact(&self, size: usize) -> Seq<std::slice::ChunksExact<'_, T>> {
        Seq(self.chunks_exact(size))
    }
}

/// rayon's mutable slice methods.
pub trait ParallelSliceMut<T> {
    fn par_chunks_mut(&mut self, size: usize) -> Seq<std::slice::ChunksMut<'_, T>>;
    fn par_sort_unstable(&mut self)
    where
        T: Ord;
    fn par_sort_unstable_by_key<K: Ord, F: FnMut(&T) -> K>(&mut self, key: F);
}

impl<T> ParallelSliceMut<T> for [T] {
    fn par_chunks_mut(&mut self, size: usize) -> Seq<std::slice::ChunksMut<'_, T>> {
        Seq(self.chunks_mut(size))
    }

    fn par_sort_unstable(&mut self)
    where
        T: Ord,
    {
        self.sort_unstable();
    }

    fn par_sort_unstable_by_key<K: Ord, F: FnMut(&T) -> K>(&mut self, key: F) {
        self.sort_unstable_by_key(key);
    }
}

/// `par_extend` on vectors.
pub trait ParallelExtend<T> {
    fn par_extend<I: IntoParallelIterator<Item = T>>(&mut self, items: I);
}

impl<T> ParallelExtend<T> for Vec<T> {
    fn par_extend<I: IntoParallelIterator<Item = T>>(&mut self, items: I) {
        self.extend(items.into_par_iter());
    }
}

/// What `use rayon::prelude::*` brings, for the calls above.
pub mod prelude {
    pub use super::{
        IntoParallelIterator, IntoParallelRefIterator, IntoParallelRefMutIterator, ParallelExtend, ParallelSlice,
        ParallelSliceMut,
    };
}
