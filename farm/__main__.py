from farm.cli.commands import run

run()
