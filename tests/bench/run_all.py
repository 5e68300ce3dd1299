"""`make bench`: every area's benchmark (tests/bench/bench_*.py, each with main(out_dir))."""
import argparse
import importlib.util
import pathlib
import sys

HERE = pathlib.Path(__file__).resolve().parent


def main() -> int:
    parser = argparse.ArgumentParser()
    parser.add_argument("--out", default=str(HERE.parents[1] / "docs" / "bench"))
    parser.add_argument("--only", nargs="*", help="area names, e.g. maps bake")
    args = parser.parse_args()
    sys.path.insert(0, str(HERE.parent))
    for path in sorted(HERE.glob("bench_*.py")):
        area = path.stem[len("bench_"):]
        if args.only and area not in args.only:
            continue
        print(f"== {area}", flush=True)
        spec = importlib.util.spec_from_file_location(path.stem, path)
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
        module.main(pathlib.Path(args.out))
    return 0


if __name__ == "__main__":
    sys.exit(main())
