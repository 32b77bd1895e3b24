# Shortcuts; each target is one documented command (see README.md).
.PHONY: install quick test test-all reproduce-ch4 report-ch4 reproduce-ch5 reproduce-ch5-perception reproduce-ch6 reproduce-data mlflow-ui

install:
	bash scripts/install.sh

quick: install  ## a few-minute Table 4.1, printed at the end
	.venv/bin/hrc-lab experiment=ch4/table_4_1_quick hydra/launcher=joblib

test: install
	.venv/bin/python -m pytest

test-all: install  ## including slow end-to-end tests
	.venv/bin/python -m pytest -m ""

reproduce-ch4: install  ## every Ch.4 reasoning table and figure, then the committed report
	.venv/bin/hrc-lab experiment=ch4/table_4_1 hydra/launcher=joblib
	.venv/bin/hrc-lab experiment=ch4/fig_4_7 hydra/launcher=joblib
	.venv/bin/hrc-lab experiment=ch4/practical hydra/launcher=joblib
	.venv/bin/hrc-lab experiment=ch4/fig_4_9 hydra/launcher=joblib
	.venv/bin/hrc-lab-report ch4_reasoning

report-ch4:
	.venv/bin/hrc-lab-report ch4_reasoning

reproduce-ch5: install  ## Fig. 5.7 and the planner columns of Table 5.2, then the committed report
	.venv/bin/hrc-lab experiment=ch5/fig_5_7 hydra/launcher=joblib
	.venv/bin/hrc-lab experiment=ch5/table_5_2_planner hydra/launcher=joblib
	.venv/bin/hrc-lab-report ch5_planner

reproduce-ch5-perception: install  ## Fig. 5.5/5.6 and Table 5.2 end to end from generated videos, then the report
	.venv/bin/hrc-lab experiment=ch5/fig_5_6 hydra/launcher=joblib
	.venv/bin/hrc-lab experiment=ch5/table_5_2 hydra/launcher=joblib
	.venv/bin/hrc-lab-report ch5_perception

reproduce-ch6: install  ## Table 6.1 and the single-image row of Table 6.2, then the committed report
	.venv/bin/hrc-lab experiment=ch6/table_6_1 hydra/launcher=joblib
	.venv/bin/hrc-lab experiment=ch6/table_6_2_single hydra/launcher=joblib
	.venv/bin/hrc-lab-report ch6_grasp

reproduce-data: install  ## every demonstration set (runs/data/*.hdf5), the videos, then the committed report
	.venv/bin/hrc-lab experiment=data/collect_ch4 hydra/launcher=joblib
	.venv/bin/hrc-lab experiment=data/collect_ch3 hydra/launcher=joblib
	.venv/bin/hrc-lab experiment=data/render_demo env=package_to_order_4of5
	.venv/bin/hrc-lab experiment=data/render_demo env=package_to_order_3of5 env.sim.case=2
	.venv/bin/hrc-lab experiment=data/render_demo env=error_correction_one_object_case1
	.venv/bin/hrc-lab experiment=data/render_demo env=error_correction_two_object_case2
	.venv/bin/hrc-lab-report data_demonstrations

mlflow-ui:  ## http://127.0.0.1:5000
	.venv/bin/mlflow ui --backend-store-uri sqlite:///runs/mlflow.db --host 127.0.0.1 --port 5000 --workers 1
