"""`python -m hola_ray.experiment`: the command (`hola_ray.experiment.command`)."""

from hola_ray.experiment.command import script

if __name__ == "__main__":
    script()
