// Storage on cache-line boundaries for the arrays the step loop streams in whole vectors.
#pragma once

#include <cstddef>
#include <new>
#include <vector>

namespace ldem {

inline constexpr std::size_t kCacheLine = 64;

// A std::allocator whose blocks start on a cache line: a 512-bit load or store at an index that
// is a multiple of 8 then touches one line, not two.
template <class T> struct CacheLineAllocator {
  using value_type = T;
  CacheLineAllocator() = default;
  template <class U> CacheLineAllocator(const CacheLineAllocator<U>&) noexcept {}
  T* allocate(std::size_t n) {
    return static_cast<T*>(::operator new (n * sizeof(T), std::align_val_t{kCacheLine}));
  }
  void deallocate(T* p, std::size_t) noexcept {
    ::operator delete (p, std::align_val_t{kCacheLine});
  }
  template <class U> bool operator==(const CacheLineAllocator<U>&) const noexcept { return true; }
};

template <class T> using AlignedVector = std::vector<T, CacheLineAllocator<T>>;

// n rounded up to whole cache lines of doubles.
constexpr std::size_t round_up_to_line(std::size_t n) {
  constexpr std::size_t per_line = kCacheLine / sizeof(double);
  return (n + per_line - 1) / per_line * per_line;
}

} // namespace ldem
