// The output files when a write fails: a full disk is stood in for by /dev/full (every write
// to it fails with ENOSPC), reached through a symbolic link where a file's temporary name
// would be.
#include "io/output.hpp"
#include "util/error.hpp"

#include <filesystem>
#include <fstream>
#include <gtest/gtest.h>
#include <string>
#include <unistd.h>

namespace ldem {
namespace {

namespace fs = std::filesystem;

// A folder of its own, removed at the end.
struct Folder {
  fs::path dir;
  Folder() {
    char name[] = "/tmp/ldem_output_XXXXXX";
    dir = mkdtemp(name);
  }
  ~Folder() { fs::remove_all(dir); }
};

// The path of a file `name` in f whose temporary version is on the full device.
std::string on_full_disk(const Folder& f, const char* name) {
  const std::string path = (f.dir / name).string();
  fs::create_symlink("/dev/full", path + ".part");
  return path;
}

// A whole file (a snapshot, summary.json) whose write fails is not renamed to its final name,
// its temporary file is gone, and the error names it.
TEST(OutputFile, WholeFileThatFailsIsNeverRenamed) {
  if (!fs::exists("/dev/full"))
    GTEST_SKIP() << "no /dev/full";
  Folder f;
  const std::string path = on_full_disk(f, "lattice_000001.vtu");
  try {
    OutputFile out(path);
    out.write(std::string(1 << 20, 'x')); // more than stdio's buffer: fails here
    out.commit();
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("lattice_000001.vtu: write failed"), std::string::npos)
        << e.what();
  }
  EXPECT_FALSE(fs::exists(path));
  EXPECT_FALSE(fs::is_symlink(path + ".part"));
}

// The same when the failure shows only at the end (the data was in stdio's buffer).
TEST(OutputFile, WholeFileThatFailsAtCommitIsNeverRenamed) {
  if (!fs::exists("/dev/full"))
    GTEST_SKIP() << "no /dev/full";
  Folder f;
  const std::string path = on_full_disk(f, "summary.json");
  EXPECT_THROW(write_file(path, "{}\n"), InputError);
  EXPECT_FALSE(fs::exists(path));
}

// A whole file dropped before commit() (an error elsewhere while it was written) leaves
// nothing: neither the final name nor its temporary file.
TEST(OutputFile, WholeFileDroppedBeforeCommitLeavesNothing) {
  Folder f;
  const std::string path = (f.dir / "lattice_000002.vtu").string();
  {
    OutputFile out(path);
    out.write("<?xml");
  }
  EXPECT_FALSE(fs::exists(path));
  EXPECT_FALSE(fs::exists(path + ".part"));
}

// A log (energy.csv) whose flush fails is not renamed either; the error says where its whole
// rows are kept.
TEST(OutputFile, LogThatFailsKeepsItsTemporaryName) {
  if (!fs::exists("/dev/full"))
    GTEST_SKIP() << "no /dev/full";
  Folder f;
  const std::string path = on_full_disk(f, "energy.csv");
  try {
    OutputFile out(path, OutputFile::Kind::Log);
    out.write("time,elastic\n");
    out.write("0,0\n");
    out.flush();
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("energy.csv.part"), std::string::npos) << e.what();
  }
  EXPECT_FALSE(fs::exists(path));
}

// A log that is complete is renamed into place with every row, by commit() or when dropped
// (an interrupted run keeps what it wrote).
TEST(OutputFile, LogIsRenamedWhole) {
  Folder f;
  const std::string path = (f.dir / "events.csv").string();
  {
    OutputFile out(path, OutputFile::Kind::Log);
    out.write("bar,event\n");
    out.write("7,broken\n");
  }
  std::ifstream in(path);
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  EXPECT_EQ(text, "bar,event\n7,broken\n");
  EXPECT_FALSE(fs::exists(path + ".part"));
}

} // namespace
} // namespace ldem
