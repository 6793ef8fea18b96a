from .cli import main

# guarded: a bake's worker processes (Dask's nanny spawns them) import the main module again
if __name__ == "__main__":
    raise SystemExit(main())
