// One function per subcommand; each lives in its own cmd_*.cpp file.
#pragma once

namespace relief::cli {

int run_roundtrip(int argc, char** argv);
int run_encode_chunk(int argc, char** argv);
int run_decode_chunk(int argc, char** argv);
int run_eval(int argc, char** argv);
int run_compress(int argc, char** argv);
int run_append(int argc, char** argv);
int run_stream(int argc, char** argv);
int run_preview(int argc, char** argv);
int run_query(int argc, char** argv);
int run_decompress(int argc, char** argv);
int run_info(int argc, char** argv);
int run_stats(int argc, char** argv);
int run_check(int argc, char** argv);
int run_shard_plan(int argc, char** argv);
int run_shard_partition(int argc, char** argv);
int run_shard_encode(int argc, char** argv);
int run_merge(int argc, char** argv);

}  // namespace relief::cli
