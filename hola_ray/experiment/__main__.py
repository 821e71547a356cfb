"""`python -m hola_ray.experiment`: the command (`hola_ray.experiment.command`), re-run first
under the fixed hash seed (`hola_ray.progress.fixed_hash_seed`) before anything heavy is
imported."""

import sys

if __name__ == "__main__":
    from hola_ray.progress import fixed_hash_seed, leave

    fixed_hash_seed("hola_ray.experiment", sys.argv[1:])
    from hola_ray.experiment.command import main

    leave(main())
