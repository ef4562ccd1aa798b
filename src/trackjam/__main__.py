from trackjam.console import main

main()
