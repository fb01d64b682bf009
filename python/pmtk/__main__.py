"""python3 -m pmtk check FILE...: reads and checks each pmtk file as pmtk.read does and prints
'# ok: N records, checksum xxh3:...' (pm-info's last line); a bad file is one line on stderr,
'pmtk: MESSAGE', and exit 1 (docs/cli.md). python3 -m pmtk header FILE: the header as JSON."""
import json
import sys

from . import FormatError, read


def main(argv):
    if len(argv) < 2 or argv[0] not in ("check", "header") or argv[0] == "header" and len(argv) != 2:
        print("usage: python3 -m pmtk check FILE... | header FILE", file=sys.stderr)
        return 2
    for path in argv[1:]:
        try:
            f = read(path)
        except FormatError as e:
            print("pmtk: %s" % e, file=sys.stderr)
            return 1
        except OSError as e:
            print("pmtk: cannot read '%s': %s" % (path, e.strerror), file=sys.stderr)
            return 3 if e.errno not in (2, 20, 21) else 1
        if argv[0] == "header":
            print(json.dumps(f.header, indent=1))
        else:
            print("# ok: %d records, checksum xxh3:%016x" % (len(f), f.checksum))
    return 0


sys.exit(main(sys.argv[1:]))
