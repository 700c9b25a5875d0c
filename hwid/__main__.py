from hwid.cli import main

main()
