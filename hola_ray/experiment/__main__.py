"""`python -m hola_ray.experiment`: the command's `script` (`hola_ray.experiment.command`),
which re-runs it under the fixed hash seed (`hola_ray.process.fixed_hash_seed`) before
anything heavy is imported."""

if __name__ == "__main__":
    from hola_ray.experiment.command import script

    script()
