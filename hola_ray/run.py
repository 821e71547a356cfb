"""`python -m hola_ray.run`: the main job (`hola_ray.commands.run`), kept at this name as
the command every page starts with; `python -m hola_ray run` is the same."""

if __name__ == "__main__":
    from hola_ray.commands.run import script

    script()
