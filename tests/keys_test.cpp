// CURVE key files (protocol/curve_keys.h) and `rayfarm keygen`.
#include <doctest/doctest.h>

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <future>

#include "protocol/curve_keys.h"
#include "tests/run_command.h"
#include "tests/test_files.h"
#include "tests/test_paths.h"
#include "tracer/error.h"

using namespace rayfarm;
using namespace rayfarm::protocol;
namespace fs = std::filesystem;

namespace {

unsigned mode_of(const fs::path& p) {
  struct stat st {};
  REQUIRE(::stat(p.c_str(), &st) == 0);
  return st.st_mode & 0777;
}

}  // namespace

TEST_CASE("keys: Debian's libzmq has CURVE") {
  CHECK(zmq_has("curve"));
  CHECK_NOTHROW(require_curve());
}

TEST_CASE("keys: keygen writes a secret file only its owner can read, and the matching public key") {
  const fs::path dir = test::scratch_dir("keys");
  const CurveKeyPair written = write_key_files((dir / "w1").string());
  CHECK(mode_of(dir / "w1.key") == 0600);
  CHECK(mode_of(dir / "w1.pub") == 0644);
  const CurveKeyPair loaded = load_secret_key((dir / "w1.key").string());
  CHECK(loaded.secret_key == written.secret_key);
  CHECK(loaded.public_key == written.public_key);  // derived from the secret
  CHECK(load_public_key((dir / "w1.pub").string()) == written.public_key);
  // Never overwritten: a new pair would lock the worker out of every farm.
  CHECK_THROWS_WITH_AS(write_key_files((dir / "w1").string()), doctest::Contains("exists; not overwritten"),
                       InputError);
  fs::permissions(dir / "w1.key", fs::perms::group_read, fs::perm_options::add);
  CHECK_THROWS_WITH_AS(load_secret_key((dir / "w1.key").string()), doctest::Contains("readable by others"),
                       InputError);
  fs::remove_all(dir);
}

TEST_CASE("keys: bad key files and allow folders are errors naming the path") {
  const fs::path dir = test::scratch_dir("keys-bad");
  const std::string bad = test::write_file(dir / "bad.pub", "# comment\nnot a key\n");
  CHECK_THROWS_WITH_AS(load_public_key(bad), doctest::Contains((bad + ": expected one 40-character Z85 CURVE key").c_str()),
                       InputError);
  const std::string two = test::write_file(dir / "two.txt", std::string(40, 'a') + "\n" + std::string(40, 'b') + "\n");
  CHECK_THROWS_AS(load_public_key(two), InputError);
  CHECK_THROWS_WITH_AS(load_allowed_keys((dir / "none").string()), doctest::Contains("not a folder"), InputError);
  fs::create_directories(dir / "empty");
  CHECK_THROWS_WITH_AS(load_allowed_keys((dir / "empty").string()), doctest::Contains("no *.pub files"), InputError);
  fs::create_directories(dir / "allow");
  const CurveKeyPair a = write_key_files((dir / "allow" / "alice").string());
  const CurveKeyPair b = write_key_files((dir / "allow" / "bob").string());
  const auto keys = load_allowed_keys((dir / "allow").string());  // the *.key files are not read
  REQUIRE(keys.size() == 2);
  CHECK(keys.at(a.public_key) == "alice");
  CHECK(keys.at(b.public_key) == "bob");
  fs::remove_all(dir);
}

TEST_CASE("keys: an allow folder or *.pub others may write, or two files holding one key, are refused naming them") {
  const fs::path dir = test::scratch_dir("keys-allow-trust");
  const std::string allow = (dir / "allow").string();
  fs::create_directories(allow);
  const CurveKeyPair alice = write_key_files(allow + "/alice");
  write_key_files(allow + "/bob");
  REQUIRE(load_allowed_keys(allow).size() == 2);
  // Whoever may write the folder or a key file in it may invite a key.
  fs::permissions(allow, fs::perms::others_write, fs::perm_options::add);
  CHECK_THROWS_WITH_AS(load_allowed_keys(allow),
                       (allow + ": writable by others, who could invite a worker key of their own; run `chmod go-w " +
                        allow + "`").c_str(),
                       InputError);
  fs::permissions(allow, fs::perms::others_write, fs::perm_options::remove);
  const std::string bob = allow + "/bob.pub";
  fs::permissions(bob, fs::perms::group_write, fs::perm_options::add);
  CHECK_THROWS_WITH_AS(load_allowed_keys(allow), doctest::Contains((bob + ": writable by others").c_str()), InputError);
  fs::permissions(bob, fs::perms::group_write, fs::perm_options::remove);
  // A second file of alice's key: which name the worker had hung on the
  // order the folder was listed in.
  fs::copy_file(allow + "/alice.pub", allow + "/zed.pub");
  CHECK_THROWS_WITH_AS(load_allowed_keys(allow),
                       (allow + "/zed.pub: holds the same key as " + allow + "/alice.pub; keep one file a worker key")
                           .c_str(),
                       InputError);
  fs::remove(allow + "/zed.pub");
  CHECK(load_allowed_keys(allow).at(alice.public_key) == "alice");
  fs::remove_all(dir);
}

TEST_CASE("keys: a folder above the allow folder that others may write or own is refused naming it") {
  // Only the allow folder and its *.pub were checked: whoever could rename a
  // folder above it could put a folder of keys of their own in its place.
  const fs::path dir = test::scratch_dir("keys-allow-parents");
  const fs::path above = dir / "etc";
  const std::string allow = (above / "allow").string();
  fs::create_directories(allow);
  write_key_files(allow + "/alice");
  REQUIRE(load_allowed_keys(allow).size() == 1);  // under the test's temp folder (/tmp, sticky) and owned folders
  fs::permissions(above, fs::perms::group_write, fs::perm_options::add);
  CHECK_THROWS_WITH_AS(load_allowed_keys(allow),
                       (above.string() + ": a folder above the allow folder " + allow + " is writable by others, who "
                        "could put keys of their own in its place; run `chmod go-w " + above.string() + "`")
                           .c_str(),
                       InputError);
  // Sticky, as /tmp: others may not rename what is not theirs.
  fs::permissions(above, fs::perms::others_write | fs::perms::sticky_bit, fs::perm_options::add);
  CHECK(load_allowed_keys(allow).size() == 1);
  fs::permissions(above, fs::perms::group_write | fs::perms::others_write | fs::perms::sticky_bit,
                  fs::perm_options::remove);
  // Read through a link: the folders above the one it names are the ones that count.
  fs::create_directory_symlink(above / "allow", dir / "link");
  fs::permissions(above, fs::perms::others_write, fs::perm_options::add);
  CHECK_THROWS_WITH_AS(load_allowed_keys((dir / "link").string()), doctest::Contains(": a folder above the allow folder"),
                       InputError);
  fs::permissions(above, fs::perms::others_write, fs::perm_options::remove);
  if (::geteuid() == 0) {  // only root can give a folder away
    REQUIRE(::chown(above.c_str(), 4242, static_cast<gid_t>(-1)) == 0);
    CHECK_THROWS_WITH_AS(load_allowed_keys(allow),
                         (above.string() + ": a folder above the allow folder " + allow + " is owned by uid 4242, "
                          "neither root nor this broker's user, who could put keys of their own in its place; give it "
                          "to root or to this user")
                             .c_str(),
                         InputError);
    REQUIRE(::chown(above.c_str(), ::geteuid(), static_cast<gid_t>(-1)) == 0);
  }
  CHECK(load_allowed_keys(allow).size() == 1);
}

TEST_CASE("keys: a FIFO named as a key, or as a *.pub in an allow folder, is refused at once naming it") {
  const fs::path dir = test::scratch_dir("keys-fifo");
  fs::create_directories(dir / "allow");
  write_key_files((dir / "allow" / "alice").string());
  const std::string fifo = (dir / "allow" / "pipe.pub").string();
  REQUIRE(::mkfifo(fifo.c_str(), 0600) == 0);
  // Opening a FIFO waits for a writer: should the load block, a writer is
  // made to come and go, so that a failing test ends instead of hanging.
  auto refusal = [&](auto load) {
    auto loading = std::async(std::launch::async, [&] {
      try {
        load();
      } catch (const InputError& e) {
        return std::string(e.what());
      }
      return std::string("loaded");
    });
    bool blocked = false;
    while (loading.wait_for(std::chrono::seconds(5)) != std::future_status::ready) {
      blocked = true;
      const int fd = ::open(fifo.c_str(), O_WRONLY | O_NONBLOCK);
      if (fd >= 0) ::close(fd);
    }
    CHECK_FALSE(blocked);
    return loading.get();
  };
  CHECK(refusal([&] { load_allowed_keys((dir / "allow").string()); }) == fifo + ": not a regular file");
  CHECK(refusal([&] { load_secret_key(fifo); }) == fifo + ": not a regular file");
  fs::remove_all(dir);
}

TEST_CASE("keys: a key file cut short, or holding two keys, says what it found instead of one key") {
  const fs::path dir = test::scratch_dir("keys-found");
  const CurveKeyPair pair = write_key_files((dir / "head").string());
  const std::string pub = (dir / "head.pub").string();
  // A copy cut short: the header and 33 of the key's 40 characters.
  const std::string cut = test::write_file(dir / "cut.pub", "# rayfarm CURVE public key\n" +
                                                                pair.public_key.substr(0, 33));
  CHECK_THROWS_WITH_AS(load_public_key(cut), doctest::Contains("found a line of 33 characters"), InputError);
  const std::string two =
      test::write_file(dir / "two.pub", pair.public_key + "\n" + write_key_files((dir / "other").string()).public_key);
  CHECK_THROWS_WITH_AS(load_public_key(two), doctest::Contains("found 2 non-comment lines"), InputError);
  const std::string empty = test::write_file(dir / "empty.pub", "# rayfarm CURVE public key\n\n");
  CHECK_THROWS_WITH_AS(load_public_key(empty), doctest::Contains("found no key line"), InputError);
  // What an operator sees from the worker started with the cut copy.
  const test::CommandResult r = test::run_command(test::rayfarm_exe() + " worker --connect tcp://127.0.0.1:1" +
                                                  " --key " + (dir / "head.key").string() + " --broker-key " + cut);
  CHECK(r.exit_code == 1);
  CHECK(r.output.find(cut + ": expected one 40-character Z85 CURVE key (from `rayfarm keygen`), found a line of 33 "
                            "characters") != std::string::npos);
  CHECK(load_public_key(pub) == pair.public_key);
  fs::remove_all(dir);
}

TEST_CASE("keys: a public key given as a secret one, or a secret one as public, is refused naming the file") {
  const fs::path dir = test::scratch_dir("keys-swapped");
  write_key_files((dir / "head").string());
  const std::string pub = (dir / "head.pub").string(), key = (dir / "head.key").string();
  // Not "run chmod 600": that would make the public key load as a secret one.
  CHECK_THROWS_WITH_AS(load_secret_key(pub), doctest::Contains((pub + ": is a public key").c_str()), InputError);
  fs::permissions(pub, fs::perms::owner_read | fs::perms::owner_write, fs::perm_options::replace);
  CHECK_THROWS_WITH_AS(load_secret_key(pub), doctest::Contains((pub + ": is a public key").c_str()), InputError);
  CHECK_THROWS_WITH_AS(load_public_key(key), doctest::Contains((key + ": is a secret key").c_str()), InputError);
  fs::create_directories(dir / "allow");
  fs::copy_file(key, dir / "allow" / "w1.pub");
  CHECK_THROWS_WITH_AS(load_allowed_keys((dir / "allow").string()), doctest::Contains("w1.pub: is a secret key"),
                       InputError);
  fs::remove_all(dir);
}

TEST_CASE("keys: `rayfarm keygen -o NAME` writes NAME.key and NAME.pub") {
  const fs::path dir = test::scratch_dir("keygen");
  const std::string name = (dir / "head").string();
  const test::CommandResult r = test::run_command(test::rayfarm_exe() + " keygen -o " + name);
  CHECK(r.exit_code == 0);
  CHECK(mode_of(dir / "head.key") == 0600);
  CHECK(r.output.find(load_public_key(name + ".pub")) != std::string::npos);
  CHECK(test::run_command(test::rayfarm_exe() + " keygen -o " + name).exit_code == 1);
  // A folder is no name: it would write the hidden DIR/.key and DIR/.pub.
  const test::CommandResult folder = test::run_command(test::rayfarm_exe() + " keygen -o " + dir.string() + "/");
  CHECK(folder.exit_code == 1);
  CHECK(folder.output.find("not a key name") != std::string::npos);
  CHECK(!fs::exists(dir / ".key"));
  CHECK_THROWS_WITH_AS(write_key_files(""), doctest::Contains("not a key name"), InputError);
  fs::remove_all(dir);
}

TEST_CASE("keys: keygen refuses a folder as NAME, and a dangling link as NAME.pub, leaving no file behind") {
  const fs::path dir = test::scratch_dir("keygen-paths");
  // A folder given without its slash wrote DIR.key and DIR.pub beside it.
  fs::create_directories(dir / "keys");
  CHECK_THROWS_WITH_AS(write_key_files((dir / "keys").string()), doctest::Contains("not a key name"), InputError);
  CHECK(!fs::exists(dir / "keys.key"));
  // A dangling link passed the existence check; the secret was written, the
  // public key was not, and the secret stayed.
  fs::create_symlink(dir / "nowhere" / "w.pub", dir / "w.pub");
  CHECK_THROWS_WITH_AS(write_key_files((dir / "w").string()), doctest::Contains("w.pub exists; not overwritten"),
                       InputError);
  CHECK(!fs::exists(dir / "w.key"));
  fs::remove_all(dir);
}

TEST_CASE("keys: `rayfarm keygen -o NAME` in a missing or read-only folder names the option, NAME and the folder") {
  // It said "nodir/k.key: cannot create (No such file or directory)": no option, and a path never typed.
  const fs::path dir = test::scratch_dir("keygen-folder");
  const std::string missing = (dir / "nodir" / "k").string();
  const test::CommandResult r = test::run_command(test::rayfarm_exe() + " keygen -o " + missing);
  CHECK(r.exit_code == 1);
  CHECK(r.output == "rayfarm: -o " + missing + ": cannot write " + missing + ".key (no directory " +
                        (dir / "nodir").string() + ")\n");
  const test::CommandResult long_form = test::run_command(test::rayfarm_exe() + " keygen --output " + missing);
  CHECK(long_form.output.rfind("rayfarm: --output " + missing + ": cannot write", 0) == 0);
  // A folder it may not write in: the reason, after the option and NAME.
  fs::create_directories(dir / "ro");
  fs::permissions(dir / "ro", fs::perms::owner_read | fs::perms::owner_exec, fs::perm_options::replace);
  const std::string ro = (dir / "ro" / "k").string();
  const test::CommandResult read_only = test::run_command(test::rayfarm_exe() + " keygen -o " + ro);
  if (::geteuid() != 0) {  // root writes anyway
    CHECK(read_only.exit_code == 1);
    CHECK(read_only.output == "rayfarm: -o " + ro + ": cannot create " + ro + ".key (Permission denied)\n");
  }
  fs::permissions(dir / "ro", fs::perms::owner_all, fs::perm_options::replace);
  fs::remove_all(dir);
}

TEST_CASE("keys: `rayfarm keygen -o NAME.key` is refused, not written as NAME.key.key") {
  const fs::path dir = test::scratch_dir("keygen-suffix");
  for (const std::string ext : {".key", ".pub"}) {
    const std::string name = (dir / ("head" + ext)).string();
    const test::CommandResult r = test::run_command(test::rayfarm_exe() + " keygen -o " + name);
    CHECK(r.exit_code == 1);
    const std::string message = "'" + name + "': give the name without " + ext;
    CHECK(r.output.find(message) != std::string::npos);
  }
  CHECK(test::files_in(dir) == 0);
  fs::remove_all(dir);
}
