#!/usr/bin/python3
"""A replay check for CI: re-simulates replay files on a fulcrum-server and fails on divergence.

    /usr/bin/python3 replay_check.py --server 127.0.0.1:50051 recordings/*.replay
    /usr/bin/python3 replay_check.py --server ADDR --download world1-1.replay --save out.replay

Prints one line per replay ("FILE: OK: 600 ticks match, ..." or "FILE: DIVERGED at tick 37:
...") and exits 0 when every replay verifies, 1 when one diverges or cannot be read, 2 on a bad
command line. Replays come from `fulcrum replay record`, `fulcrum replay download` or
World.download_replay.
"""

import argparse
import sys

import fulcrum


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("replays", nargs="*", help="replay files")
    parser.add_argument("--server", default="127.0.0.1:50051", help="HOST:PORT")
    parser.add_argument("--token-file", help="the server's --token-file")
    parser.add_argument("--download", action="append", default=[], metavar="NAME",
                        help="also check a replay recorded on the server (repeatable)")
    parser.add_argument("--save", help="with one --download: keep the downloaded file here")
    args = parser.parse_args(argv)
    if not args.replays and not args.download:
        parser.error("no replay to check: give files or --download NAME")
    if args.save and len(args.download) != 1:
        parser.error("--save needs exactly one --download")

    failed = 0
    try:
        with fulcrum.connect(args.server, token_file=args.token_file) as client:
            sources = [(path, lambda p=path: fulcrum.Replay.load(p)) for path in args.replays]
            sources += [(name, lambda n=name: client.download_replay(n, path=args.save))
                        for name in args.download]
            for label, load in sources:
                try:
                    report = client.verify_replay(load())
                except fulcrum.FulcrumError as error:
                    print(f"{label}: ERROR: {error}")
                    failed += 1
                    continue
                print(f"{label}: {report}")
                failed += not report.ok
    except fulcrum.FulcrumError as error:  # connecting, or a token file that cannot be read
        print(f"replay_check: {error}", file=sys.stderr)
        return 1
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
