// Storage on cache-line boundaries for the arrays the step loop streams in whole vectors.
#pragma once

#include <cstddef>
#include <new>
#include <sys/mman.h>
#include <utility>
#include <vector>

namespace ldem {

inline constexpr std::size_t kCacheLine = 64;

// Blocks of at least this size start on a 2 MiB boundary and ask the kernel for huge pages
// (madvise MADV_HUGEPAGE; Linux's transparent huge pages are often enabled only where asked):
// a large body's arrays are then touched in 2 MiB pages, 512 times fewer page faults when they
// are first written (the set-up) and fewer TLB misses when the step streams them.
inline constexpr std::size_t kHugePage = std::size_t{2} << 20;
inline constexpr std::size_t kHugeBlock = 8 * kHugePage;

// A std::allocator whose blocks start on a cache line: a 512-bit load or store at an index that
// is a multiple of 8 then touches one line, not two. Large blocks: see kHugeBlock.
template <class T> struct CacheLineAllocator {
  using value_type = T;
  CacheLineAllocator() = default;
  template <class U> CacheLineAllocator(const CacheLineAllocator<U>&) noexcept {}
  T* allocate(std::size_t n) {
    const std::size_t bytes = n * sizeof(T);
    if (bytes < kHugeBlock)
      return static_cast<T*>(::operator new (bytes, std::align_val_t{kCacheLine}));
    void* p = ::operator new (bytes, std::align_val_t{kHugePage});
    madvise(p, bytes / kHugePage * kHugePage, MADV_HUGEPAGE); // (a hint: its own whole pages)
    return static_cast<T*>(p);
  }
  void deallocate(T* p, std::size_t n) noexcept {
    ::operator delete (p, std::align_val_t{n * sizeof(T) < kHugeBlock ? kCacheLine : kHugePage});
  }
  template <class U> bool operator==(const CacheLineAllocator<U>&) const noexcept { return true; }
};

template <class T> using AlignedVector = std::vector<T, CacheLineAllocator<T>>;

// A CacheLineAllocator that leaves the elements of a vector grown without a value (vector(n),
// resize(n)) unset: for large arrays that the threads then write together, so that their first
// writes (a page fault per page) are shared too. Such a vector must be written before it is
// read; assign(n, value) still sets every element.
template <class T> struct UnsetAllocator : CacheLineAllocator<T> {
  template <class U> struct rebind { using other = UnsetAllocator<U>; };
  UnsetAllocator() = default;
  template <class U> UnsetAllocator(const UnsetAllocator<U>&) noexcept {}
  template <class U> void construct(U* p) noexcept { ::new (static_cast<void*>(p)) U; }
  template <class U, class... A> void construct(U* p, A&&... a) {
    ::new (static_cast<void*>(p)) U(std::forward<A>(a)...);
  }
};

template <class T> using UnsetVector = std::vector<T, UnsetAllocator<T>>;

// n rounded up to whole cache lines of doubles.
constexpr std::size_t round_up_to_line(std::size_t n) {
  constexpr std::size_t per_line = kCacheLine / sizeof(double);
  return (n + per_line - 1) / per_line * per_line;
}

} // namespace ldem
