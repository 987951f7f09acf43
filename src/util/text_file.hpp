// Reading a text file that a user names (a case, a resolved case): only a regular file, and
// only up to a size no such file needs, so that a device or a directory given by mistake is
// refused at once instead of read for ever.
#pragma once

#include <cstdint>
#include <string>

namespace ldem {

// The largest text file read: 64 MiB (a case with a few thousand node sets is under 1 MiB).
inline constexpr std::uintmax_t kMaxTextFile = std::uintmax_t{64} << 20;

// The whole of `path`, `what` naming it in messages ("the case file"). Throws InputError
// naming the path when it is missing or unreadable, not a regular file (a directory, a device,
// a pipe), or larger than kMaxTextFile.
std::string read_text_file(const std::string& path, const std::string& what);

} // namespace ldem
