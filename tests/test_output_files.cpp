// cli::OutputFile, the one way every pneu program opens an output path: a regular file (or none
// yet) written beside its resolved target and renamed over it, keeping its mode and owner; a
// symbolic link followed, never replaced; a device, a FIFO or a standard stream written directly,
// never renamed over nor removed; two outputs on one file refused.
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <fcntl.h>
#include <sys/stat.h>
#include <sys/sysmacros.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>
#include <thread>

#include "pneu/config/cli.hpp"
#include "support/child_process.hpp"

namespace {

namespace fs = std::filesystem;
using pneu::cli::OutputFile;
using pneu::cli::OutputKind;
using pneu::cli::UsageError;
using pneu::test::slurp;
using ::testing::HasSubstr;

bool is_char_device(const fs::path& p) {
  struct stat st {};
  return ::lstat(p.c_str(), &st) == 0 && S_ISCHR(st.st_mode);
}

mode_t mode_of(const fs::path& p) {
  struct stat st {};
  EXPECT_EQ(::stat(p.c_str(), &st), 0) << p;
  return st.st_mode & 07777;
}

class OutputFiles : public ::testing::Test {
 protected:
  // A character device like /dev/null (1, 3) or /dev/full (1, 7): as root made in the test's own
  // directory (a test run on code that replaces devices then harms nothing of the machine's); as
  // a normal user the system's own, which that user cannot replace anyway.
  [[nodiscard]] fs::path device(const char* name, unsigned minor) const {
    if (::geteuid() != 0) return fs::path("/dev") / name;
    const fs::path p = dir_ / name;
    EXPECT_EQ(::mknod(p.c_str(), S_IFCHR | 0666, makedev(1, minor)), 0) << std::strerror(errno);
    return p;
  }
  // The names in the test's directory besides `keep`: no temporary file left behind.
  [[nodiscard]] std::vector<std::string> names() const {
    std::vector<std::string> n;
    for (const auto& e : fs::directory_iterator(dir_)) n.push_back(e.path().filename().string());
    std::sort(n.begin(), n.end());
    return n;
  }
  pneu::test::TestDir dir_{"pneu_output_files_"};
};

TEST_F(OutputFiles, ANewFileAppearsWholeAtCommitWithTheUmasksMode) {
  const fs::path p = dir_ / "new.csv";
  const mode_t old_mask = ::umask(022);
  {
    OutputFile out(p, "--out");
    out.stream() << "a,b\n1,2\n";
    EXPECT_FALSE(fs::exists(p)) << "nothing at the path before commit";
    out.commit();
  }
  ::umask(old_mask);
  EXPECT_EQ(slurp(p), "a,b\n1,2\n");
  EXPECT_EQ(mode_of(p), 0644u);
  EXPECT_EQ(names(), std::vector<std::string>{"new.csv"});
}

TEST_F(OutputFiles, WithoutCommitTheExistingFileIsLeftAsItWasAndNoTemporaryFileRemains) {
  const fs::path p = dir_ / "kept.csv";
  std::ofstream(p) << "earlier\n";
  {
    OutputFile out(p, "--out");
    out.stream() << "half of it";
  }
  EXPECT_EQ(slurp(p), "earlier\n");
  EXPECT_EQ(names(), std::vector<std::string>{"kept.csv"});
}

TEST_F(OutputFiles, AReplacedFileKeepsItsMode) {
  const fs::path p = dir_ / "mode.csv";
  std::ofstream(p) << "earlier\n";
  fs::permissions(p, fs::perms::owner_read | fs::perms::owner_write | fs::perms::group_read);  // 640
  OutputFile out(p, "--out");
  out.stream() << "now\n";
  out.commit();
  EXPECT_EQ(slurp(p), "now\n");
  EXPECT_EQ(mode_of(p), 0640u);
}

TEST_F(OutputFiles, AReplacedFileKeepsItsOwner) {
  if (::geteuid() != 0) GTEST_SKIP() << "giving a file another owner needs root";
  const fs::path p = dir_ / "owner.csv";
  std::ofstream(p) << "earlier\n";
  ASSERT_EQ(::chown(p.c_str(), 4321, 4322), 0);
  OutputFile out(p, "--out");
  out.stream() << "now\n";
  out.commit();
  struct stat st {};
  ASSERT_EQ(::stat(p.c_str(), &st), 0);
  EXPECT_EQ(st.st_uid, 4321u);
  EXPECT_EQ(st.st_gid, 4322u);
}

TEST_F(OutputFiles, ASymbolicLinkIsFollowedTheTargetGetsTheContentAndTheLinkStaysALink) {
  fs::create_directory(dir_ / "elsewhere");
  const fs::path target = dir_ / "elsewhere" / "tgt.json";
  std::ofstream(target) << "earlier, and longer than what replaces it\n";
  fs::create_symlink("elsewhere/tgt.json", dir_ / "lnk");  // relative, as ln -s makes them
  OutputFile out(dir_ / "lnk", "--summary-json");
  out.stream() << "{}\n";
  out.commit();
  EXPECT_TRUE(fs::is_symlink(dir_ / "lnk"));
  EXPECT_EQ(fs::read_symlink(dir_ / "lnk"), "elsewhere/tgt.json");
  EXPECT_EQ(slurp(target), "{}\n");
  EXPECT_EQ(names(), (std::vector<std::string>{"elsewhere", "lnk"})) << "the temporary file was beside the target";
}

TEST_F(OutputFiles, ADanglingSymbolicLinkCreatesTheFileItNames) {
  fs::create_symlink(dir_ / "tgt.csv", dir_ / "lnk");
  OutputFile out(dir_ / "lnk", "--out");
  out.stream() << "x\n";
  out.commit();
  EXPECT_TRUE(fs::is_symlink(dir_ / "lnk"));
  EXPECT_EQ(slurp(dir_ / "tgt.csv"), "x\n");
}

TEST_F(OutputFiles, ANewOrRegularFileIsNotWrittenDirectly) {
  EXPECT_FALSE(OutputFile(dir_ / "new.csv", "--out").direct()) << "nothing there yet";
  std::ofstream(dir_ / "old.csv") << "x\n";
  EXPECT_FALSE(OutputFile(dir_ / "old.csv", "--out").direct());
}

TEST_F(OutputFiles, ACharacterDeviceIsWrittenDirectlyAndStaysADevice) {
  const fs::path null = device("null", 3);
  OutputFile out(null, "--summary-json");
  EXPECT_TRUE(out.direct());
  out.stream() << "{}\n";
  out.commit();
  EXPECT_TRUE(is_char_device(null));
}

TEST_F(OutputFiles, AWriteErrorOnADeviceFailsTheCommitNamingTheOption) {
  const fs::path full = device("full", 7);  // every write: ENOSPC
  OutputFile out(full, "--identify");
  out.stream() << "plant:\n";
  try {
    out.commit();
    ADD_FAILURE() << "a write to " << full << " succeeded";
  } catch (const std::runtime_error& e) {
    EXPECT_THAT(e.what(), HasSubstr("--identify " + full.string() + ": write failed: No space left on device"));
  }
  EXPECT_TRUE(is_char_device(full));
}

TEST_F(OutputFiles, AFifoIsWrittenDirectlyToItsReader) {
  const fs::path fifo = dir_ / "fifo";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  std::string received;
  std::thread reader([&] { received = slurp(fifo); });  // opens it, reads to the end
  try {
    OutputFile out(fifo, "--events");
    out.stream() << "{\"event\":\"start\"}\n";
    out.commit();
  } catch (const std::exception& e) {
    ADD_FAILURE() << e.what();
    if (const int fd = ::open(fifo.c_str(), O_WRONLY | O_NONBLOCK); fd >= 0) ::close(fd);  // the reader: EOF
  }
  reader.join();
  EXPECT_EQ(received, "{\"event\":\"start\"}\n");
  struct stat st {};
  ASSERT_EQ(::lstat(fifo.c_str(), &st), 0);
  EXPECT_TRUE(S_ISFIFO(st.st_mode)) << "still a FIFO";
}

TEST_F(OutputFiles, DevStdoutWritesToTheDescriptorItNames) {
  // In a child whose standard output is a pipe, as `pneud --summary-json /dev/stdout | jq`.
  int pipe_fds[2];
  ASSERT_EQ(::pipe(pipe_fds), 0);
  const pid_t pid = ::fork();
  ASSERT_GE(pid, 0);
  if (pid == 0) {
    ::dup2(pipe_fds[1], 1);
    ::close(pipe_fds[0]);
    ::close(pipe_fds[1]);
    int code = 0;
    try {
      OutputFile out("/dev/stdout", "--summary-json");
      out.stream() << "{\"through\":\"the pipe\"}\n";
      out.commit();
    } catch (...) {
      code = 1;
    }
    std::fflush(stdout);
    ::_exit(code);
  }
  ::close(pipe_fds[1]);
  std::string got;
  char buf[256];
  for (ssize_t n; (n = ::read(pipe_fds[0], buf, sizeof buf)) > 0;) got.append(buf, static_cast<std::size_t>(n));
  ::close(pipe_fds[0]);
  int status = 0;
  ASSERT_EQ(::waitpid(pid, &status, 0), pid);
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0);
  EXPECT_EQ(got, "{\"through\":\"the pipe\"}\n");
  EXPECT_TRUE(fs::is_symlink("/dev/stdout") || fs::is_character_file("/dev/stdout")) << "/dev/stdout untouched";
}

TEST_F(OutputFiles, ALiveRecordIsWrittenIntoTheFileAsItGoes) {
  const fs::path p = dir_ / "outputs.csv";
  std::ofstream(p) << "an earlier run's record\n";
  OutputFile out(p, "--outputs", OutputKind::kLive);
  std::fputs("t_s,u_p_v,u_n_v\n", out.c_file());
  std::fflush(out.c_file());
  EXPECT_EQ(slurp(p), "t_s,u_p_v,u_n_v\n") << "readable while it is written";
  out.commit();
  EXPECT_EQ(names(), std::vector<std::string>{"outputs.csv"});
}

TEST_F(OutputFiles, ADirectoryOrAMissingDirectoryIsRefusedNamingTheOption) {
  EXPECT_THAT([&] { OutputFile out(dir_, "--out"); },
              ::testing::ThrowsMessage<std::runtime_error>(HasSubstr("--out " + dir_.path().string() + ": cannot open for writing: it is a directory")));
  EXPECT_THAT([&] { OutputFile out(dir_ / "no" / "x.csv", "--out"); },
              ::testing::ThrowsMessage<std::runtime_error>(HasSubstr("cannot open for writing: the directory")));
}

TEST_F(OutputFiles, TwoOutputsOnOneFileAreRefusedNamingBothOptions) {
  const std::string same = (dir_ / "same.csv").string();
  EXPECT_THAT([&] { pneu::cli::refuse_same_file({{"--trajectory", same}, {"--events", same}}); },
              ::testing::ThrowsMessage<UsageError>(HasSubstr("--trajectory " + same + " and --events " + same + " name the same file")));
  // Through a link, through a path spelled otherwise, and as a hard link of an existing file.
  fs::create_symlink("same.csv", dir_ / "lnk");
  EXPECT_THROW(pneu::cli::refuse_same_file({{"--trajectory", same}, {"--events", (dir_ / "lnk").string()}}), UsageError);
  EXPECT_THROW(pneu::cli::refuse_same_file({{"--trajectory", same}, {"--events", (dir_ / "." / "same.csv").string()}}), UsageError);
  std::ofstream(same) << "x";
  fs::create_hard_link(same, dir_ / "hard.csv");
  EXPECT_THROW(pneu::cli::refuse_same_file({{"--out", same}, {"--scenarios-out", (dir_ / "hard.csv").string()}}), UsageError);
  // Different files, and a device two outputs may share.
  EXPECT_NO_THROW(pneu::cli::refuse_same_file({{"--trajectory", same}, {"--events", (dir_ / "other.csv").string()}}));
  EXPECT_NO_THROW(pneu::cli::refuse_same_file({{"--trajectory", "/dev/null"}, {"--events", "/dev/null"}}));
}

}  // namespace
