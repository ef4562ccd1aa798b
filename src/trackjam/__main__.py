from trackjam.cli import app

app(prog_name="trackjam")
