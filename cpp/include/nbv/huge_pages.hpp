// Large, short-lived arrays backed by transparent huge pages where the kernel offers them.
//
// A fresh array of tens of megabytes (glibc maps every allocation over 32 MB anew, and unmaps it
// when freed) costs a page fault per 4 KiB page when first written. On this project's virtual
// machine a fault costs about 4 microseconds, so filling a 60 MB scratch array spent more time in
// the kernel than in the loop that filled it. Asking for huge pages (MADV_HUGEPAGE, honoured
// where /sys/kernel/mm/transparent_hugepage/enabled is "madvise" or "always") makes that one
// fault per 2 MiB. Elsewhere the advice is ignored and nothing changes.
#pragma once

#include <sys/mman.h>

#include <cstddef>
#include <cstdlib>
#include <new>
#include <type_traits>
#include <utility>
#include <vector>

namespace nbv {

template <class T>
struct HugePageAllocator {
  using value_type = T;
  static constexpr std::size_t kHuge = std::size_t(2) << 20;  // one huge page
  static constexpr std::size_t kMin = 4 * kHuge;              // smaller arrays: plain operator new

  HugePageAllocator() = default;
  template <class U>
  HugePageAllocator(const HugePageAllocator<U>&) {}  // NOLINT: rebinding

  T* allocate(std::size_t n) {
    const std::size_t bytes = n * sizeof(T);
    if (bytes < kMin) return static_cast<T*>(::operator new(bytes));
    const std::size_t size = (bytes + kHuge - 1) / kHuge * kHuge;
    void* p = std::aligned_alloc(kHuge, size);
    if (!p) throw std::bad_alloc();
    madvise(p, size, MADV_HUGEPAGE);  // a hint: failure leaves ordinary pages
    return static_cast<T*>(p);
  }
  void deallocate(T* p, std::size_t n) {
    if (n * sizeof(T) < kMin)
      ::operator delete(p);
    else
      std::free(p);
  }
  template <class U>
  bool operator==(const HugePageAllocator<U>&) const {
    return true;
  }
  template <class U>
  bool operator!=(const HugePageAllocator<U>&) const {
    return false;
  }
};

/// A std::vector whose large buffers ask for huge pages.
template <class T>
using HugeVector = std::vector<T, HugePageAllocator<T>>;

/// HugePageAllocator whose value-initialisation (resize(n), vector(n)) leaves trivial elements
/// uninitialised: for an array that is filled right after, in parallel, so that its pages are
/// first touched (and zeroed by the kernel) by the threads that fill them, not by one memset.
template <class T>
struct UninitHugePageAllocator : HugePageAllocator<T> {
  template <class U>
  struct rebind {
    using other = UninitHugePageAllocator<U>;
  };
  UninitHugePageAllocator() = default;
  template <class U>
  UninitHugePageAllocator(const UninitHugePageAllocator<U>&) {}  // NOLINT: rebinding
  template <class U>
  void construct(U* p) noexcept(std::is_nothrow_default_constructible_v<U>) {
    ::new (static_cast<void*>(p)) U;  // default-initialised: no zeroing for trivial types
  }
  template <class U, class... Args>
  void construct(U* p, Args&&... args) {
    ::new (static_cast<void*>(p)) U(std::forward<Args>(args)...);
  }
};

/// A HugeVector whose resize leaves trivial elements uninitialised (UninitHugePageAllocator):
/// every element must be written before it is read.
template <class T>
using HugeBuffer = std::vector<T, UninitHugePageAllocator<T>>;

}  // namespace nbv
