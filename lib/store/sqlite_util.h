// A thin RAII layer over the SQLite C API for lib/store. Private to the store:
// sqlite3.h never reaches a public header.
#pragma once

#include <sqlite3.h>

#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "relief/status.h"

namespace relief::store {

// How long a connection waits for another connection's lock before it gives
// up with SQLITE_BUSY. Appends commit in well under a second, so 5 s only
// runs out when another process holds a write transaction open for long.
inline constexpr int kBusyTimeoutMs = 5000;

// Turns a failed SQLite call into a Relief status whose message is
// "<path>: <what>: <sqlite message>". The code follows what went wrong:
// busy/locked and file trouble -> kIoError, not a database or damaged ->
// kFormatError, too big -> kLimitExceeded, the rest -> kInternal.
Status sqlite_error(sqlite3* db, int rc, const std::string& path, std::string_view what);

struct ConnectionCloser {
  void operator()(sqlite3* db) const { sqlite3_close_v2(db); }
};
using Connection = std::unique_ptr<sqlite3, ConnectionCloser>;

// Opens `file` with SQLITE_OPEN_* `flags` and sets up what every Relief
// connection needs: extended result codes, the busy timeout, and defensive
// settings for files that may come from anywhere. Errors read
// "<path>: <what>: ..." with `path` the archive the caller is about (which
// may differ from `file`, e.g. the temporary file of create()).
Result<Connection> open_connection(const std::string& file, int flags, const std::string& path,
                                   std::string_view what);

// The URI that opens `path` read-only as immutable: SQLite then takes no
// locks and creates no -shm or -wal file, which is right only when nothing
// writes the file meanwhile (read-only media). Open it with SQLITE_OPEN_URI.
std::string immutable_uri(const std::string& path);

// kFormatError "<path>: truncated: ..." when `path` starts with a valid SQLite
// header whose database size (pages x page size, offsets 16 and 28, trusted
// when the version-valid-for number matches the change counter) exceeds the
// file's size: SQLite itself would only say "not a database" or "malformed".
// OK for anything else, including files that are not SQLite at all.
Status check_not_truncated(const std::string& path);

// Closes the connection and reports a failure (sqlite3_close, not _v2: a
// close that cannot finish is an error we want to see, e.g. when creating).
Status close_connection(Connection connection, const std::string& path);

// Runs SQL that returns no rows (several statements separated by ';').
Status exec(sqlite3* db, const char* sql, const std::string& path, std::string_view what);

// `sql` with every run of white space outside quotes made one space, and
// none kept next to ( ) , ; or at either end. SQLite stores each CREATE
// statement's text in the file as given: the compact form of the schema
// takes about 500 bytes less, a page or so of a small archive. The SQL must
// hold no "--" comment: joined into one line, it would swallow what follows.
std::string compact_sql(std::string_view sql);

// The name SQLite should open for a file system path. SQLite on Debian is
// built with URI file names on, so a relative path that happens to start
// with "file:" would be parsed as a URI; "./" keeps it a plain path.
std::string sqlite_file_name(const std::string& path);

// One prepared statement. Binding errors are kept and reported by the next
// step(), so a statement with many parameters reads as a flat list of binds.
class Statement {
 public:
  // `what` names the statement in error messages ("insert chunk").
  static Result<std::unique_ptr<Statement>> prepare(sqlite3* db, std::string_view sql,
                                                    const std::string& path, std::string what);
  ~Statement();
  Statement(const Statement&) = delete;
  Statement& operator=(const Statement&) = delete;

  // Text and blob arguments are bound without a copy: they must stay alive
  // until reset().
  void bind_int64(int index, std::int64_t value);
  void bind_double(int index, double value);
  void bind_text(int index, std::string_view value);
  void bind_blob(int index, const std::uint8_t* data, std::size_t size);
  void bind_null(int index);

  // One step: true when a row is ready, false when the statement is done.
  Result<bool> step();
  // Steps to the end, for statements that return no rows.
  Status run();
  // Rewinds and clears the bindings. A SELECT that is not reset keeps its read
  // snapshot (and in WAL mode blocks checkpoints), so every use ends here.
  void reset();

  int column_type(int column) const;
  std::int64_t column_int64(int column) const;
  double column_double(int column) const;
  std::string column_text(int column) const;
  // Copies a BLOB (or TEXT) column into `out`.
  Status column_bytes(int column, std::vector<std::uint8_t>& out) const;

  const std::string& what() const { return what_; }

 private:
  Statement(sqlite3* db, sqlite3_stmt* stmt, const std::string& path, std::string what);
  void note_bind(int rc);

  sqlite3* db_;
  sqlite3_stmt* stmt_;
  const std::string& path_;  // owned by the archive, which outlives its statements
  std::string what_;
  int bind_rc_ = SQLITE_OK;  // first failed bind, reported by step()
};

// Resets a statement when the scope ends, whatever path leaves it.
class StatementScope {
 public:
  explicit StatementScope(Statement& statement) : statement_(statement) {}
  ~StatementScope() { statement_.reset(); }
  StatementScope(const StatementScope&) = delete;
  StatementScope& operator=(const StatementScope&) = delete;

 private:
  Statement& statement_;
};

// A transaction that rolls back unless commit() succeeded. Write transactions
// start with BEGIN IMMEDIATE: they take the write lock up front (waiting up to
// the busy timeout), so they never fail half-way with SQLITE_BUSY_SNAPSHOT.
// Read transactions pin one snapshot for several SELECTs.
class Transaction {
 public:
  enum class Kind { kRead, kWrite };
  Transaction(sqlite3* db, const std::string& path) : db_(db), path_(path) {}
  ~Transaction();
  Transaction(const Transaction&) = delete;
  Transaction& operator=(const Transaction&) = delete;

  Status begin(Kind kind);
  Status commit();

 private:
  sqlite3* db_;
  const std::string& path_;
  bool active_ = false;
};

}  // namespace relief::store
