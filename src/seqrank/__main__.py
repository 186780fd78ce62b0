from seqrank.cli import main

raise SystemExit(main())
