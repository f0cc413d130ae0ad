from farm.cli.entry import run

run()
