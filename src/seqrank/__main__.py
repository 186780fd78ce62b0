from seqrank.entry import main

raise SystemExit(main())
